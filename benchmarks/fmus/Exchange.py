"""Benchmark-only FMU: 16 Real inputs u1..u16 and 16 Real outputs y_i = u_i (direct feedthrough).

Built on the greyfmu slave base, so its get/set go through ``GreyfmuSlave``'s compiled
exchange; ``ExchangeGeneric`` is the same FMU with pythonfmu's generic get/set, the
"before" of benchmarks/bench_exchange.py.
"""

from typing import Any

from _slave import GreyfmuSlave

WIDTH = 16


class Exchange(GreyfmuSlave):
    description = "Benchmark FMU: y_i = u_i for i = 1..16 (direct feedthrough)"
    output_dependencies = {f"y{i}": [f"u{i}"] for i in range(1, WIDTH + 1)}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        for i in range(1, WIDTH + 1):
            self.input(f"u{i}", float(i), f"Input {i}")
        for i in range(1, WIDTH + 1):
            self.output(f"y{i}", f"Output {i} = input {i}", lambda name=f"u{i}": getattr(self, name))

    def build(self) -> None:
        """Nothing to build: the outputs are the inputs."""

    def advance(self, t: float, h: float) -> None:
        """Stateless."""
