"""``cosim``: run, validate, inspect, sweep, tune and pack SSP systems and single FMUs (FMI 2.0, 3.0; CS, ME).

Exit status: 0 done, 1 the run failed, crashed or timed out (results up to the last
good step are kept), 2 the input is wrong (nothing was run), 130/143 the run was
stopped by SIGINT/SIGTERM (results kept).  No traceback unless --debug.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import warnings
from importlib.metadata import version
from pathlib import Path

from .errors import CosimError, CosimWarning, RunError, SetupError
from .regression.commands import COMMANDS, add_commands
from .safeio import parse_size, unpack_limit


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="cosim", description=__doc__.splitlines()[0].replace("``", ""))
    p.add_argument("--debug", action="store_true", help="show Python tracebacks")
    p.add_argument("--version", action="version", version=f"cosim (greyfmu) {version('greyfmu')}")
    sub = p.add_subparsers(dest="command", required=True)

    def common(sp):
        sp.add_argument("path", help="scenario folder (SystemStructure.ssd), .ssd file or .ssp archive "
                                     "(run, validate, info: or one .fmu)")
        sp.add_argument("--fmu-dir", action="append", default=[], metavar="DIR",
                        help="folder to look in for FMUs the scenario does not carry (repeatable)")
        sp.add_argument("--max-unpacked", metavar="SIZE", help="most an .ssp archive may expand to, e.g. 4G "
                        "(default: $COSIM_MAX_UNPACKED_BYTES or 2G)")
        sp.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help=argparse.SUPPRESS)

    def strict(sp):
        sp.add_argument("--strict", action="store_true", help=STRICT_HELP)

    run = sub.add_parser("run", help="run a system and write CSV results (and a plot)")
    common(run)
    run.add_argument("--start", "--start-time", type=_seconds, dest="start",
                     help="start time [s] (default: DefaultExperiment or 0)")
    run.add_argument("--stop", "--stop-time", type=_seconds, dest="stop",
                     help="stop time [s] (default: DefaultExperiment; an FMU without one: start + 1)")
    run.add_argument("--step", type=_seconds, help="communication step [s] (default: SSD annotation; an FMU's "
                                                "DefaultExperiment stepSize, else fmpy's automatic interval)")
    single_options(run)
    strict(run)
    run.add_argument("--algorithm", choices=["jacobi", "gauss-seidel"], help="default: jacobi")
    run.add_argument("--param-set", action="append", default=[], metavar="X.ssv",
                     help="parameter set applied last, names 'component.variable' (repeatable)")
    run.add_argument("--output", "-o", metavar="FILE",
                     help="result CSV, or Parquet for a .parquet name (default: "
                          "results/<name>__<param set>...csv, one name per scenario and parameter sets)")
    run.add_argument("--plot", nargs="?", const="", metavar="PNG",
                     help="write a plot of --signals (default file: the result's name with .png)")
    run.add_argument("--report", nargs="?", const="", metavar="HTML",
                     help="write a self-contained HTML report of the run: plot, metrics per event, parameters, "
                          "metadata (default file: the result's name with .html)")
    run.add_argument("--signals", nargs="+", metavar="GLOB",
                     help="signals to plot, one panel per argument; 'a,b' overlays a and b in one panel "
                          "(default: each controller's set-point with its controlled variable, then its outputs; "
                          "without controllers, every connected output)")
    run.add_argument("--fmu-log", choices=["errors", "all", "off"], default="errors",
                     help="FMU log messages kept to explain a failure: the FMUs' status categories "
                          "(default), every category, or none (fastest)")
    run.add_argument("--loops", choices=["iterate", "delay"], default="iterate",
                     help="algebraic loops of direct feedthrough: solved by iteration at every communication "
                          "point (default), or broken by one step of delay, as libcosim runs them")
    run.add_argument("--loop-tolerance", type=float, nargs=2, default=(1e-10, 1e-12), metavar=("RTOL", "ATOL"),
                     help="convergence of a loop: every loop output changes by at most ATOL + RTOL·|y| in an "
                          "iteration (default 1e-10 1e-12)")
    run.add_argument("--loop-iterations", type=int, default=100, help="iterations before a loop fails (100)")
    run.add_argument("--relaxation", type=float, default=1.0, help="relaxation factor in (0, 1] (1: plain "
                                                                    "fixed point)")
    run.add_argument("--loop-method", choices=["newton", "fixed-point"], default="newton",
                     help="loop solver: fixed-point sweeps, Newton's method where they are slow or diverge "
                          "(newton, default), or the sweeps alone (fixed-point)")
    run.add_argument("--kernel", choices=["auto", "native", "python"], default="auto",
                     help="stepping loop: the compiled one where it can run, else the Python one (auto, "
                          "default; the metadata says which and why), the compiled one or an error (native), "
                          "or the Python one (python); the results are the same")
    run.add_argument("--threads", type=int, default=1, metavar="N",
                     help="threads making the doSteps of each Jacobi step in parallel on the compiled kernel "
                          "(default 1; same results; pays only for FMUs of tens of µs per step)")
    run.add_argument("--quiet", "-q", action="store_true", help=QUIET_HELP)
    run.add_argument("--timeout", type=float, metavar="SECONDS",
                     help="end the run after SECONDS (status 'timeout', exit 1); an FMU call still not "
                          "returned 2 s later is killed, the rows so far kept")
    run.add_argument("--isolate", action="store_true",
                     help="run each FMU in a process of its own: an FMU that crashes (abort, segfault, exit) "
                          "ends the run as that component's failure (status 'crashed', exit 1), every row kept")
    run.add_argument("--call-timeout", type=float, metavar="SECONDS",
                     help="with --isolate: an FMU call that does not return within SECONDS kills that "
                          "component's process (status 'timeout', exit 1)")

    validate = sub.add_parser("validate", help="check a system without running it")
    common(validate)
    validate.add_argument("--fmi-type", choices=["CoSimulation", "ModelExchange"], help=FMI_TYPE_HELP)
    strict(validate)
    validate.add_argument("--param-set", action="append", default=[], metavar="X.ssv",
                          help="parameter set checked as cosim run applies it, last (repeatable)")

    info = sub.add_parser("info", help="list components, connections and parameters")
    common(info)
    info.add_argument("--fmi-type", choices=["CoSimulation", "ModelExchange"], help=FMI_TYPE_HELP)
    info.add_argument("--program", action="store_true",
                      help="also print the step's program: the operations of one communication step, compiled "
                           "from the plan (no FMU is loaded)")
    info.add_argument("--algorithm", choices=["jacobi", "gauss-seidel"],
                      help="the algorithm whose step --program prints (default: the SSD's, else jacobi)")

    metrics = sub.add_parser("metrics", help="IAE, ISE, ITAE, overshoot, rise and settling time of a result")
    metrics.add_argument("result", help="result CSV or Parquet file written by cosim run")
    metrics.add_argument("--signal", required=True, help="controlled variable, e.g. plant.y")
    metrics.add_argument("--setpoint", required=True, help="setpoint signal, e.g. setpoint.y")
    metrics.add_argument("--disturbance", action="append", default=[], metavar="SIGNAL",
                         help="a disturbance signal whose steps are events of their own, e.g. load.y (repeatable)")
    metrics.add_argument("--t0", type=float, help="measure one window from t0 instead of one row per event "
                                                  "(default end: the end of the run)")
    metrics.add_argument("--t1", type=float, help="end of that one window (default start: the setpoint's last change)")
    metrics.add_argument("--band", type=float, default=0.02, help="settling band, fraction of the step (0.02)")
    metrics.add_argument("--json", action="store_true", help="print the metrics as JSON")
    metrics.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help=argparse.SUPPRESS)

    report = sub.add_parser("report", help="one self-contained HTML page of a run: plot, metrics per event, "
                                           "parameters, metadata")
    report.add_argument("result", help="result CSV or Parquet file written by cosim run (its JSON beside it)")
    report.add_argument("--output", "-o", metavar="HTML", help="default: the result's name with .html")
    report.add_argument("--signals", nargs="+", metavar="GLOB", help="plot panels, as for cosim run")
    report.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help=argparse.SUPPRESS)

    add_commands(sub)   # compare, verify (cosim.regression)

    pack = sub.add_parser("pack", help="pack a scenario folder into a standard .ssp archive")
    common(pack)
    pack.add_argument("-o", "--output", required=True, metavar="X.ssp")

    sweep = sub.add_parser("sweep", help="run every combination of parameter values (and seeds) in parallel")
    common(sweep)
    sweep.add_argument("--set", action="append", default=[], metavar="NAME=V1,V2", dest="sets",
                       help="values of a parameter 'component.variable', typed by the FMU variable; an item "
                            "START:STOP:COUNT is COUNT values evenly spaced (repeatable; the product is run)")
    sweep.add_argument("--seeds", metavar="1..20|1,5,9",
                       help="seeds, one run per seed and combination, set on every parameter named 'seed'")
    sweep.add_argument("--seed-parameter", action="append", default=[], metavar="COMP.VAR",
                       help="the parameter(s) --seeds sets (default: every component's 'seed')")
    sweep.add_argument("--metrics", nargs="+", default=[], metavar="SIGNAL:SETPOINT",
                       help="step metrics per run (IAE, ISE, ITAE, overshoot, rise and settling time), "
                            "e.g. plant.y:setpoint.y")
    sweep.add_argument("--param-set", action="append", default=[], metavar="X.ssv",
                       help="parameter set applied to every run before the swept values (repeatable)")
    input_options(sweep)
    strict(sweep)
    batch_options(sweep)
    sweep.add_argument("--scheduler", metavar="ADDRESS",
                       help="run on a Dask distributed cluster (tcp://host:8786), or 'local:N' for a local "
                            "Dask cluster of N worker processes")
    sweep.add_argument("--output", "-o", metavar="DIR",
                       help="folder for sweep.csv, runs/ and, with pyarrow, sweep.parquet (default: results/<name>_sweep)")
    sweep.add_argument("--force", action="store_true", help="rerun runs already done")
    sweep.add_argument("--no-run-files", dest="run_files", action="store_false",
                       help="write the sweep table only, not each run's runs/<id>.csv, .json and .ssv "
                            "(a rerun then reruns every run)")
    sweep.add_argument("--fresh-instances", dest="reuse", action="store_false",
                       help="read, check and instantiate every run afresh instead of keeping the scenario and "
                            "the reset FMU instances in each worker across its runs")
    sweep.add_argument("--quiet", "-q", action="store_true", help=QUIET_HELP)

    new = sub.add_parser("new", help="write a scenario that closes a loop of one of our controllers (or any "
                                     "controller FMU) around your plant FMU, and say what is left to wire")
    new.add_argument("folder", help="the scenario folder to write (SystemStructure.ssd, controller.ssv, README.md, "
                                    "resources/)")
    new.add_argument("--plant", required=True, metavar="PLANT.fmu", help="the plant FMU (any tool's)")
    new.add_argument("--controller", default="PID", metavar="NAME|X.fmu",
                     help="one of our controllers by name (greyfmu info lists them) or a controller FMU (default PID)")
    new.add_argument("--plant-input", metavar="NAME", help="the plant input the controller drives (default: the "
                                                           "first Real input, by unit where the controller declares one)")
    new.add_argument("--plant-output", metavar="NAME", help="the plant output the controller measures (default: the "
                                                            "first Real output, by unit where possible)")
    new.add_argument("--plant-interface", choices=["CoSimulation", "ModelExchange"],
                     help="the plant's interface (default: Model Exchange where it has one, integrated by the master)")
    new.add_argument("--setpoint", type=float, metavar="VALUE", help="the set-point after its step (default: the "
                                                                      "plant output's start value + 1)")
    new.add_argument("--step", type=_seconds, help="communication step [s] (default: one that divides the "
                                                    "controller's sample time, no longer than the plant's own step)")
    new.add_argument("--stop", type=_seconds, help="stop time [s] (default: the plant's DefaultExperiment, else 10)")
    new.add_argument("--force", action="store_true", help="overwrite a scenario already in the folder")

    from .tune.cli import add_parser as tune_parser
    tune_parser(sub, common, input_options, batch_options, QUIET_HELP)

    completion = sub.add_parser("completion", help="print a shell completion script (e.g. "
                                                   "eval \"$(cosim completion bash)\")")
    completion.add_argument("shell", choices=["bash", "zsh", "tcsh"])
    return p


QUIET_HELP = "no progress bar and no informational lines: errors and warnings only"
STRICT_HELP = ("turn cosim's warnings into errors (exit 2, nothing run): a master step that is longer than a sampled "
               "FMU's sample time or does not divide it, an input the FMU's law reads left unconnected, a sample "
               "time left at the FMU's default that is not the master step, a model description that breaks a rule "
               "other masters tolerate (cosim.read.conformance)")


def _seconds(text: str) -> float:
    """An argparse type: a finite number (argparse's error names the option and the text given)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text} is not a finite number of seconds")
    return value


def _say(args, text: str) -> None:
    """An informational line on stdout, which --quiet leaves out."""
    if not getattr(args, "quiet", False):
        print(text)


def _progress(args) -> bool:
    """A progress bar only where a person watches: not --quiet, and stderr a terminal (a log
    file gets no carriage-return-separated bar)."""
    return not args.quiet and sys.stderr.isatty()


FMI_TYPE_HELP = "the interface of an FMU that has both (default: CoSimulation); a single .fmu only"


def batch_options(sp: argparse.ArgumentParser) -> None:
    """--start, --stop, --step and --workers of the commands that make many runs (sweep, tune)."""
    sp.add_argument("--start", type=_seconds, help="start time [s] (default: DefaultExperiment or 0)")
    sp.add_argument("--stop", type=_seconds, help="stop time [s] (default: DefaultExperiment)")
    sp.add_argument("--step", type=_seconds, help="communication step [s] (default: SSD annotation)")
    sp.add_argument("--workers", type=int, metavar="N", help="processes of the local pool (default: one per core)")


def input_options(run: argparse.ArgumentParser) -> None:
    """--start-value and --input-file (`cosim.plan.prepare`, `cosim.plan.inputs`), with fmpy simulate's names."""
    run.add_argument("--start-value", "--start-values", action="append", default=[], metavar="NAME=VALUE",
                     dest="start_values", help="start value of a parameter or input, applied after the parameter "
                     "sets: the variable's name for a single FMU, 'component.variable' in a system (repeatable)")
    run.add_argument("--input-file", metavar="CSV", help="input table: a 'time' column, then one column per input "
                     "(names as for --start-value); Reals interpolated linearly, discrete inputs held, a repeated "
                     "time is an event (fmpy's format and rules)")


def single_options(run: argparse.ArgumentParser) -> None:
    """The options of `cosim.plan.prepare` and `cosim.plan.inputs`, with fmpy simulate's names."""
    input_options(run)
    run.add_argument("--output-interval", type=float, metavar="SECONDS",
                     help="communication step, at which results are recorded (fmpy's name for --step)")
    run.add_argument("--fmi-type", choices=["CoSimulation", "ModelExchange"], help=FMI_TYPE_HELP)


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        limit = getattr(args, "max_unpacked", None)
        with unpack_limit(parse_size(limit, "--max-unpacked") if limit else None), warnings.catch_warnings():
            # cosim's own warnings (an undriven root output): one line each, as they come, a repeated
            # one once (a plan built again for --start-value warns again)
            warnings.simplefilter("default", RuntimeWarning)
            warnings.showwarning = _print_warning
            _strict(args)
            code = {"run": _run, "validate": _validate, "info": _info, "pack": _pack, "metrics": _metrics,
                    "report": _report, "sweep": _sweep, "new": _new, "tune": _tune, "completion": _completion,
                    **COMMANDS}[args.command](args)
        sys.stdout.flush()  # a closed pipe is reported here, not at interpreter exit
        return code
    except CosimError as e:
        return _fail(e, args.debug)
    except CosimWarning as w:  # --strict
        return _fail(SetupError(f"{w} (--strict makes this warning an error)"), args.debug)
    except BrokenPipeError:  # `cosim info | head -1`: the reader has gone; end quietly, as cat does
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1


def _strict(args) -> None:
    """With --strict, cosim's warnings (`cosim.errors.CosimWarning`) raise instead of printing;
    called again after a filter for RuntimeWarning, which would otherwise come first."""
    if getattr(args, "strict", False):
        warnings.simplefilter("error", CosimWarning)


def plural(count: int, noun: str) -> str:
    """``1 FMU``, ``2 FMUs``."""
    return f"{count} {noun}{'' if count == 1 else 's'}"


def _completion(args) -> int:
    """The shell's completion script for every subcommand and option (shtab: generated from
    the parser itself, so it never disagrees with --help)."""
    import shtab

    print(shtab.complete(_parser(), args.shell))
    return 0


def _fail(e: CosimError, debug: bool) -> int:
    """One paragraph on stderr, and the exit status of the error's code (`Errc.exit_status`: 1
    for a failed run, 2 for input that cannot be run)."""
    if debug:
        raise e
    print(f"cosim: the run failed ({e.code.value}): {e}" if e.code.run_failed else f"cosim: error: {e}",
          file=sys.stderr)
    return e.code.exit_status


def _run(args) -> int:
    from .run.instances import Unzipped
    from .record.journal import journal_path
    from .record.outputs import RESULT_SUFFIXES, check_not_in_sweep, check_output, plot_suffixes, scenario_files
    from .safeio import lock_output, lock_path, partial_path
    from .plan.prepare import prepare
    from .run.simulation import isolation_of
    from .run.supervisor import supervise

    if args.timeout is not None and not (math.isfinite(args.timeout) and args.timeout > 0):
        raise SetupError(f"--timeout {args.timeout}: give a positive number of seconds.", element="--timeout")
    isolation_of(args.isolate, args.call_timeout)  # refused before anything is read
    prepared = prepare(args.path, start_time=args.start, stop_time=args.stop, step_size=args.step,
                       algorithm=args.algorithm, parameter_sets=args.param_set, fmu_dirs=args.fmu_dir,
                       loops=args.loops, start_values=args.start_values, input_file=args.input_file,
                       output_interval=args.output_interval, fmi_type=args.fmi_type)
    try:
        name = prepared.plan.name or Path(args.path).resolve().stem
        output = Path(args.output) if args.output else _default_result(prepared.plan, name, args.param_set)
        own = scenario_files(prepared.plan)
        check_output(output, own, what="result file", option="--output", suffixes=RESULT_SUFFIXES,
                     companions=[output.with_suffix(".json"), journal_path(output), partial_path(output),
                                 lock_path(output)])
        check_not_in_sweep(output)
        if args.plot is not None:
            check_output(Path(args.plot or output.with_suffix(".png")), own, what="plot", option="--plot",
                         suffixes=plot_suffixes())
        if args.report is not None:
            check_output(Path(args.report or output.with_suffix(".html")), own, what="report", option="--report",
                         suffixes=(".html", ".htm"))

        for desc in prepared.plan.fmus.values():  # extracted here, so this process's later runs reuse them
            Unzipped()(desc.path)

        progress = _progress(args)  # asked here: the child's stderr is the supervisor's pipe

        def child() -> int:
            try:
                return _execute(args, prepared, name, output, progress)
            except CosimError as e:
                return _fail(e, args.debug)

        with lock_output(output):  # one writer per output, through the crash recovery
            return supervise(child, journal_path(output), timeout=args.timeout)
    finally:
        prepared.close()


#: what a default output name taken from the scenario's path is called in an error
SCENARIO_NAME = "the scenario's name"


def _default_result(plan, name: str, parameter_sets: list[str]) -> Path:
    """``results/<system name>__<set>...csv``, the names checked to be file names."""
    from .record.outputs import result_stem

    where = dict(file=plan.files.display, element="ssd:SystemStructureDescription name") if plan.name else \
        dict(what=SCENARIO_NAME)
    return Path("results") / f"{result_stem(name, parameter_sets, **where)}.csv"


def _execute(args, prepared, name: str, output: Path, progress: bool) -> int:
    """The run itself (in `cosim.run.supervisor`'s child, with a progress bar if ``progress``): exit 0,
    1 failed or timed out, 130/143 stopped by SIGINT/SIGTERM."""
    from .run.interrupts import stop_on_signals
    from .run.loops import LoopSettings
    from .present.plots import default_panels, plot
    from .present.plots import plotted
    from .record.metadata import signal_info
    from .record.results import panel, select
    from .run.simulation import run

    plan = prepared.plan
    outputs, inputs = plan.recorded()
    panels = ([select(outputs + inputs, panel(g)) for g in args.signals] if args.signals
              else default_panels(signal_info(plan), plotted(plan, outputs + inputs)))
    settings = LoopSettings(rtol=args.loop_tolerance[0], atol=args.loop_tolerance[1],
                            max_iterations=args.loop_iterations, relaxation=args.relaxation,
                            method=args.loop_method)
    grid = prepared.grid
    _say(args, f"cosim: {name}: {plural(len(plan.components), 'FMU')}, {plural(len(plan.routes), 'connection')}, "
          f"t = {grid.start:g}..{grid.stop:g} s, step {grid.step:g} s ({prepared.step_source}), "
          f"{prepared.algorithm}")
    try:
        with stop_on_signals() as stop, warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", RuntimeWarning)  # printed as cosim's own warnings
            outcome = run(prepared, output=output, progress=progress, fmu_log=args.fmu_log,
                          keep=[n for panel in panels for n in panel] if args.plot is not None else [],
                          loop_settings=settings, stop=stop, isolate=args.isolate,
                          call_timeout=args.call_timeout, kernel=args.kernel, threads=args.threads)
        for warning in caught:
            print(f"cosim: warning: {warning.message}", file=sys.stderr)
    except RunError:
        print(f"cosim: results up to the last good step kept in {output}", file=sys.stderr)
        raise
    if outcome.status == "discarded":
        print(f"cosim: warning: {outcome.message}", file=sys.stderr)
    elif outcome.status == "terminated":
        print(f"cosim: {outcome.message}", file=sys.stderr)
    _say(args, f"cosim: results: {output} ({outcome.samples} samples; metadata {output.with_suffix('.json')})")
    if stop.signum is not None:
        print(f"cosim: {outcome.message} Results up to there kept in {output}", file=sys.stderr)
        return 1 if stop.status() == "timeout" else 128 + stop.signum
    if args.plot is not None:
        png = plot(outcome.result, panels, args.plot or output.with_suffix(".png"), scenario=name,
                   metadata=outcome.metadata)
        _say(args, f"cosim: plot: {png}")
    if args.report is not None:
        from .present.report import write_report
        page = write_report(output, args.report or output.with_suffix(".html"), panels=panels)
        _say(args, f"cosim: report: {page}")
    return 0


def _validate(args) -> int:
    from .plan.loopcheck import check_loops
    from .read.single import is_fmu

    with _prepare_with_placeholder_grid(args) as prepared:
        plan = prepared.plan
        e = plan.experiment
        if e.step_size is not None and not is_fmu(args.path):   # a single FMU's was checked by prepare
            check_loops(plan, prepared.grid)
        stop = f"stop {e.stop_time:g} s" if e.stop_time is not None else "no stop time in the SSD (run needs --stop)"
        step = f"step {e.step_size:g} s ({e.step_size_source})" if e.step_size is not None \
            else "no step size in the SSD (run needs --step)"
        print(f"cosim: {args.path}: valid — {plural(len(plan.fmus), 'FMU')}, {plural(len(plan.routes), 'connection')}, "
              f"{plural(len(plan.start_values), 'parameter value')}; {stop}; {step}")
        for loop in plan.algebraic_loops:
            print(f"cosim: algebraic loop (run solves it by iteration; --loops delay breaks it): {loop.describe()}")
    return 0


def _prepare_with_placeholder_grid(args):
    """validate/info/pack need no grid, but check the SSD's: a stop time and step size the SSD
    does not give are placeholders (`cosim.plan.prepare.prepare_scenario`'s ``grid_placeholders``)."""
    from .plan.prepare import prepare
    from .read.single import is_fmu

    if is_fmu(args.path) and args.command == "pack":
        raise SetupError("cosim pack packs an SSP scenario; an FMU alone has no SSD to pack.",
                         file=args.path, element="cosim pack")
    return prepare(args.path, fmi_type=getattr(args, "fmi_type", None), fmu_dirs=args.fmu_dir,
                   parameter_sets=getattr(args, "param_set", []), grid_placeholders=True)


def _info(args) -> int:
    from .plan.loopcheck import LoopWarning
    from .read.single import is_fmu

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LoopWarning)   # info says what to wire instead
        prepared = _prepare_with_placeholder_grid(args)
    with prepared:
        plan = prepared.plan
        if is_fmu(args.path):
            from .present.fmuinfo import fmu_lines
            from .read.annotations import model_text

            desc = next(iter(plan.fmus.values()))
            print("\n".join(fmu_lines(desc, model_text(desc.path))))
            return 0
        e, hierarchy = plan.experiment, plan.hierarchy
        print(f"system {plan.name!r} ({plan.files.display})")
        print(f"  experiment: start {e.start_time}, stop {e.stop_time}, step {e.step_size} "
              f"({e.step_size_source or 'none in the SSD'}), algorithm {e.algorithm or 'jacobi'}")
        if hierarchy is not None and (hierarchy.systems or hierarchy.connectors):
            print(f"hierarchy (names are paths relative to the root system '{plan.system_name}'):")
            _print_system(hierarchy, 1)
            for o in plan.system_outputs.values():
                print(f"  recorded: {o.name} = {o.transform.text(o.source)}" if o.component is not None
                      else f"  recorded: {o.name} = {o.transform.offset:g} (undriven: a constant)")
        print("components:")
        for name, desc in plan.fmus.items():
            print(f"  {name}: {desc.path.name} (FMI {desc.fmi_version}, {desc.generation_tool}, "
                  f"GUID {desc.guid})")
            solver = plan.solvers.get(name)
            print(f"    interface {desc.kind} (implementation=\"{plan.components[name].implementation}\")"
                  + (f", integrated by the master: {solver.method}, rtol {solver.rtol:g}, max step "
                     f"{solver.as_dict()['max_step']}" if solver else ""))
            for v in plan.inputs[name] + plan.outputs[name]:
                print(f"    {v.causality:6} {v.type:7} {v.name}" + (f" [{v.unit}]" if v.unit else ""))
        print("connections:")
        for r in plan.routes:
            tf = "" if r.transform.identity else f" = {r.transform.text(r.source)}"
            print(f"  {r.label}{tf}")
        print("parameters:")
        for sv in plan.start_values:
            print(f"  {sv.component}.{sv.variable.name} = {sv.value}  ({sv.origin})")
        if plan.feedthrough_sequence:
            print("direct feedthrough resolved at each step in the order: " + ", ".join(plan.feedthrough_sequence))
        if args.program:
            from .run.program import compile as compile_program

            print("\n".join(compile_program(plan, args.algorithm or prepared.algorithm).listing()))
    return 0


def _print_system(node, depth: int) -> None:
    """One line per system (with its connectors) and per component, indented by depth."""
    connectors = ", ".join(f"{c.kind} {c.name}" for c in node.connectors)
    print("  " * depth + f"{node.path or node.name} (system{': ' + connectors if connectors else ''})")
    for comp in node.components:
        print("  " * (depth + 1) + comp)
    for sub in node.systems:
        _print_system(sub, depth + 1)


def _pack(args) -> int:
    from .record.outputs import check_output, scenario_files
    from .present.pack import pack

    with _prepare_with_placeholder_grid(args) as prepared:
        output = Path(args.output)
        check_output(output, scenario_files(prepared.plan), what="packed archive", option="--output",
                     suffixes=[".ssp"], companions=[output.with_suffix(output.suffix + ".part")])
        out = pack(prepared.plan, output)
    print(f"cosim: packed {out}")
    return 0


def _metrics(args) -> int:
    import json

    from .present.metrics import EVENT_METRICS, METRICS, Event, event_metrics, find_events, step_response
    from .record.results import read
    from .record.results import select

    result = read(args.result)
    names = [n for n in result.dtype.names if n != "time"]
    y, r = (select(names, [name], option=option)[0]
            for name, option in ((args.signal, "--signal"), (args.setpoint, "--setpoint")))
    time = result["time"]
    if len(time) < 2:
        raise SetupError(f"{len(time)} sample(s): the metrics need two or more.", file=args.result)
    for option, value in (("--t0", args.t0), ("--t1", args.t1)):
        if value is not None and not time[0] <= value <= time[-1]:
            raise SetupError(f"{option} {value:g} is outside the result's time range [{time[0]:g}, {time[-1]:g}].",
                             file=args.result, element=option)
    if args.t0 is not None and args.t1 is not None and args.t1 <= args.t0:
        raise SetupError(f"--t1 {args.t1:g} is not after --t0 {args.t0:g}.", file=args.result, element="--t1")
    if args.t0 is not None or args.t1 is not None:
        window = step_response(time, result[y], result[r], t0=args.t0, t1=args.t1, band=args.band)
        t0 = args.t0 if args.t0 is not None else float("nan")
        events = [Event("window", "--t0/--t1", t0, args.t1 if args.t1 is not None else float(time[-1]),
                        float("nan"), float("nan"))]
        rows, keys = [window], METRICS
    else:
        disturbances = {d: result[d] for d in (select(names, [g], option="--disturbance")[0] for g in args.disturbance)}
        events = find_events(time, (r, result[r]), disturbances)
        rows, keys = event_metrics(time, result[y], result[r], events, band=args.band), EVENT_METRICS
    if args.json:
        def number(x: float) -> float | None:   # JSON has no NaN: an undefined metric is null
            return x if x == x else None
        print(json.dumps([{"event": ev.kind, "signal": ev.signal, "t0": number(ev.t0), "t1": ev.t1,
                           "before": number(ev.before), "after": number(ev.after),
                           **{k: number(row.values[k]) for k in keys}, "undefined": row.undefined}
                          for ev, row in zip(events, rows)]))
        return 0
    print(f"{y} following {r} ({args.result}): {len(rows)} event(s), one row each; "
          f"settling band ±{100 * args.band:g} %")
    header = {"IAE": "IAE", "ISE": "ISE", "ITAE": "ITAE", "overshoot": "overshoot [%]", "rise_time": "rise [s]",
              "settling_time": "settling [s]", "peak_error": "peak error"}
    labels = [f"{i} {'window' if ev.kind == 'window' else ev.describe()}" for i, ev in enumerate(events, 1)]
    spans = [f"{ev.t0:g}..{ev.t1:g}" for ev in events]
    wl, ws = max(map(len, labels + ["event"])), max(map(len, spans + ["window [s]"]))
    cells = [[f"{row.values[k]:.5g}" if row.values[k] == row.values[k] else "-" for k in keys] for row in rows]
    widths = [max(len(header[k]), *(len(c[j]) for c in cells)) for j, k in enumerate(keys)]
    print(f"  {'event':{wl}}  {'window [s]':{ws}}" + "".join(f"  {header[k]:>{w}}" for k, w in zip(keys, widths)))
    for label, span, row_cells in zip(labels, spans, cells):
        print(f"  {label:{wl}}  {span:{ws}}" + "".join(f"  {c:>{w}}" for c, w in zip(row_cells, widths)))
    for i, row in enumerate(rows, 1):
        for what, reason in row.grouped():
            print(f"  event {i}: {', '.join(what)} undefined: {reason}")
    return 0


def _report(args) -> int:
    from .record.outputs import check_output
    from .present.report import write_report
    from .record.results import panel, read, select

    result = Path(args.result)
    page = Path(args.output or result.with_suffix(".html"))
    check_output(page, {result.resolve(), result.with_suffix(".json").resolve()}, what="report",
                 option="--output", suffixes=(".html", ".htm"), owner="the result's")
    panels = None
    if args.signals:
        names = [n for n in read(args.result).dtype.names if n != "time"]
        panels = [select(names, panel(g)) for g in args.signals]
    print(f"cosim: report: {write_report(result, page, panels=panels)}")
    return 0


def _sweep(args) -> int:
    from .record.outputs import result_stem
    from .sweep import parse_seeds, parse_set, read_table, sweep

    sets = dict(parse_set(text) for text in args.sets)
    seeds = parse_seeds(args.seeds) if args.seeds else []
    if not sets and not seeds:
        raise SetupError("nothing to sweep: give --set NAME=V1,V2 and/or --seeds.", element="cosim sweep")
    if args.workers is not None and args.workers < 1:
        raise SetupError(f"--workers {args.workers}: give at least 1.", element="--workers")
    output = Path(args.output) if args.output else \
        Path("results") / f"{result_stem(Path(args.path).resolve().stem, args.param_set, what=SCENARIO_NAME)}_sweep"
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("always", RuntimeWarning)   # cosim's own warnings, one line each, as they come
            warnings.showwarning = _print_warning
            _strict(args)
            result = sweep(args.path, sets, seeds=seeds, seed_parameters=args.seed_parameter, metrics=args.metrics,
                           parameter_sets=args.param_set, start_time=args.start, stop_time=args.stop,
                           step_size=args.step, fmu_dirs=args.fmu_dir, start_values=args.start_values,
                           input_file=args.input_file, output=output, run_files=args.run_files, reuse=args.reuse,
                           executor=args.scheduler or "process", workers=args.workers, force=args.force,
                           progress=_progress(args))
    except KeyboardInterrupt:
        table = output / "sweep.csv"
        kept = len(read_table(table)) if table.is_file() else 0
        print(f"cosim: sweep interrupted; {kept} finished runs are in {table} (run the same command "
              "again to do the rest)", file=sys.stderr)
        return 130
    for row in result.failed:
        print(f"cosim: run {row['run_id']} failed: {row['message']}", file=sys.stderr)
    _print_undefined_metrics(result.rows, args.metrics)
    _say(args, f"cosim: sweep: {len(result.rows)} runs ({result.ran} ran now, {result.skipped} already done and "
          f"skipped, {len(result.failed)} failed); table {result.csv}"
          f"{f' and {result.parquet}' if result.parquet else ''}"
          + (f", results in {output / 'runs'}" if args.run_files else ""))
    return 1 if result.failed else 0


def _new(args) -> int:
    from .scaffold import new_scenario

    made = new_scenario(args.folder, args.plant, args.controller, plant_input=args.plant_input,
                        plant_output=args.plant_output, plant_interface=args.plant_interface, setpoint=args.setpoint, step=args.step, stop=args.stop,
                        force=args.force)
    print(f"cosim: new scenario {made.folder}: " + ", ".join(str(f.relative_to(made.folder)) for f in made.files))
    for line in made.wiring:
        print(f"  wired: {line}")
    for line in made.left:
        print(f"  left to wire: {line}")
    print(f"cosim: tune the controller in {made.folder / 'controller.ssv'}; run it with: cosim run {made.folder} --plot")
    return 0


def _tune(args) -> int:
    from .tune.cli import run

    return run(args, _say, _progress(args), _print_warning)


def _print_warning(message, *_) -> None:
    """``warnings.showwarning`` for the sweep: the message alone, on one line of stderr."""
    print(f"cosim: warning: {message}", file=sys.stderr)


def _print_undefined_metrics(rows, metrics: list[str]) -> None:
    """For each metric column with undefined values: in how many runs, and the first run's reason."""
    from .present.metrics import reasons_of
    from .sweep import parse_metric

    done = [row for row in rows if row.get("status") != "failed"]
    for m in map(parse_metric, metrics):
        for column in m.columns():
            missing = [row for row in done if row.get(column) is None or row[column] != row[column]]
            if missing:
                why = reasons_of(missing[0].get(m.reason_column())).get(column.rsplit(":", 1)[1])
                print(f"cosim: {column} undefined in {len(missing)} of {len(done)} runs"
                      + (f" (run {missing[0]['run_id']}: {why})" if why else ""), file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
