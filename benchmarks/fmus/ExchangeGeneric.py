"""Benchmark-only FMU: `Exchange` with pythonfmu 0.7.0's generic get/set (Fmi2Slave's own
methods: a dictionary lookup, a type check and a getter or setter call per value reference),
the "before" of benchmarks/bench_exchange.py."""

from pythonfmu import Fmi2Slave

from Exchange import Exchange


class ExchangeGeneric(Exchange):
    description = "Benchmark FMU: Exchange with pythonfmu's generic get/set"
    get_real = Fmi2Slave.get_real
    set_real = Fmi2Slave.set_real
    get_integer = Fmi2Slave.get_integer
    set_integer = Fmi2Slave.set_integer
    get_boolean = Fmi2Slave.get_boolean
    set_boolean = Fmi2Slave.set_boolean
    get_string = Fmi2Slave.get_string
    set_string = Fmi2Slave.set_string
