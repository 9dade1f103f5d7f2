"""``cosim tune``'s options and command (hooked into `cosim.cli`)."""
from __future__ import annotations

import sys
import warnings
from collections.abc import Callable
from pathlib import Path

from ..errors import SetupError
from . import DEFAULT_EVALUATIONS
from .optimizers import METHODS, DifferentialEvolution, NelderMead


def add_parser(sub, common: Callable, input_options: Callable, batch_options: Callable, quiet_help: str) -> None:
    """The ``tune`` subcommand, with `cosim.cli`'s option groups."""
    tune = sub.add_parser("tune", help="search the parameters that minimise a control-loop objective under "
                                       "constraints (SciPy's optimisers over parallel co-simulations)")
    common(tune)
    tune.add_argument("--param", action="append", default=[], metavar="NAME=LOW:HIGH[:log]", dest="params",
                      help="a parameter 'component.variable' to tune within [LOW, HIGH], evenly in its value or "
                           "(:log) in its logarithm (repeatable)")
    tune.add_argument("--objective", action="append", default=[], metavar="[W*]METRIC:SIGNAL[:SETPOINT][@EVENTS]",
                      help="a term to minimise, e.g. ITAE:plant.y (METRIC: IAE, ISE, ITAE, overshoot, rise_time, "
                           "settling_time, peak_error; SETPOINT: default the loop's; EVENTS: all (default), set-point, "
                           "disturbance or an event's number); repeated: the weighted sum")
    tune.add_argument("--constraint", action="append", default=[], metavar="TERM<=BOUND",
                      help="a bound on a term, e.g. 'overshoot:plant.y<=10%%' or 'settling_time:plant.y<=60s' "
                           "(repeatable)")
    tune.add_argument("--disturbance", action="append", metavar="SIGNAL",
                      help="a signal whose steps are events of their own (repeatable; default: the signals driving "
                           "a plant input d, as the report finds them)")
    tune.add_argument("--method", choices=list(METHODS), default="differential-evolution",
                      help="SciPy's differential evolution (default: global, a generation in parallel, constraints) "
                           "or Nelder-Mead (local, from the scenario's values)")
    tune.add_argument("--max-evaluations", type=int, default=DEFAULT_EVALUATIONS, metavar="N",
                      help=f"the most points evaluated (default {DEFAULT_EVALUATIONS}); with --seeds each is one "
                           "run per seed")
    tune.add_argument("--popsize", type=int, default=DifferentialEvolution.popsize, metavar="K",
                      help="differential evolution: K points per parameter in a generation (default "
                           f"{DifferentialEvolution.popsize})")
    tune.add_argument("--tol", type=float, default=DifferentialEvolution.tol,
                      help="differential evolution: stop when the generation's objectives spread less than TOL "
                           f"times their mean (default {DifferentialEvolution.tol})")
    tune.add_argument("--polish", type=float, default=DifferentialEvolution.polish, metavar="SHARE",
                      help="differential evolution: the share of --max-evaluations left to refine the best point "
                           f"with Nelder-Mead (default {DifferentialEvolution.polish}; 0: none)")
    tune.add_argument("--optimizer-seed", type=int, default=0, metavar="N",
                      help="the optimiser's random seed (default 0): the same seed and settings give the same tuning")
    tune.add_argument("--seeds", metavar="1..5|1,5,9",
                      help="noise seeds: each point run once per seed (on every 'seed' parameter) and the objective "
                           "averaged, each constraint taken at its worst seed")
    tune.add_argument("--seed-parameter", action="append", default=[], metavar="COMP.VAR",
                      help="the parameter(s) --seeds sets (default: every component's 'seed')")
    tune.add_argument("--param-set", action="append", default=[], metavar="X.ssv",
                      help="parameter set applied to every run before the tuned values (repeatable)")
    input_options(tune)
    batch_options(tune)
    tune.add_argument("--scheduler", metavar="ADDRESS",
                      help="run on a Dask cluster (tls://host:8786), 'local:N' for a local one, or 'serial' for "
                           "this process")
    tune.add_argument("--output", "-o", metavar="DIR",
                      help="folder for tune.csv, best.ssv, best.csv, convergence.png and tune.html (default: "
                           "results/<name>_tune); the same command again resumes a tuning stopped half way")
    tune.add_argument("--force", action="store_true", help="start again, discarding the folder's earlier evaluations")
    tune.add_argument("--no-report", dest="report", action="store_false",
                      help="write tune.csv and best.ssv only (no best run, plot or HTML)")
    tune.add_argument("--fresh-instances", dest="reuse", action="store_false",
                      help="read, check and instantiate every run afresh instead of keeping the reset FMU instances")
    tune.add_argument("--quiet", "-q", action="store_true", help=quiet_help)


def run(args, say: Callable[[object, str], None], progress: bool, print_warning: Callable) -> int:
    """The ``tune`` command: exit 0 with a best point meeting the constraints, 1 without one
    (none completed, or none met them), 130 when interrupted (the evaluations so far kept)."""
    from ..record.outputs import result_stem
    from ..sweep import parse_seeds
    from ..sweep.table import read_table
    from . import tune

    if args.workers is not None and args.workers < 1:
        raise SetupError(f"--workers {args.workers}: give at least 1.", element="--workers")
    if args.popsize < 1:
        raise SetupError(f"--popsize {args.popsize}: give at least 1.", element="--popsize")
    if not 0 <= args.polish < 1:
        raise SetupError(f"--polish {args.polish}: give a share from 0 to below 1.", element="--polish")
    method = DifferentialEvolution(popsize=args.popsize, tol=args.tol, polish=args.polish) \
        if args.method == DifferentialEvolution.name else NelderMead()
    output = Path(args.output) if args.output else \
        Path("results") / f"{result_stem(Path(args.path).resolve().stem, args.param_set, what='the scenario name')}_tune"
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("always", RuntimeWarning)
            warnings.showwarning = print_warning
            result = tune(args.path, args.params, objective=args.objective, constraints=args.constraint,
                          method=method, max_evaluations=args.max_evaluations, seed=args.optimizer_seed,
                          seeds=parse_seeds(args.seeds) if args.seeds else (), seed_parameters=args.seed_parameter,
                          disturbances=args.disturbance, parameter_sets=args.param_set,
                          start_values=args.start_values, input_file=args.input_file, fmu_dirs=args.fmu_dir,
                          start_time=args.start, stop_time=args.stop, step_size=args.step, output=output,
                          executor=args.scheduler or "process", workers=args.workers, reuse=args.reuse,
                          force=args.force, progress=progress, report=args.report)
    except KeyboardInterrupt:
        table = output / "tune.csv"
        kept = len(read_table(table)) if table.is_file() else 0
        print(f"cosim: tuning interrupted; {kept} evaluations are in {table} (run the same command again to go on "
              "from there)", file=sys.stderr)
        return 130
    failed = result.failed
    if failed:
        print(f"cosim: {len(failed)} of {len(result.evaluations)} evaluations failed or could not be measured "
              f"(first, #{failed[0].index}: {failed[0].message}); see {result.table}", file=sys.stderr)
    best = result.best
    say(args, f"cosim: tune: {len(result.evaluations)} evaluations ({result.ran} run now), {result.message.rstrip('.')}; "
              f"{result.seconds:.3g} s; table {result.table}")
    if best is None:
        print("cosim: no evaluation completed, so there is no best point.", file=sys.stderr)
        return 1
    values = ", ".join(f"{k} = {v:.6g}" for k, v in best.values.items())
    say(args, f"cosim: best (evaluation {best.index}): {values}; objective {best.value:.6g}"
              + "".join(f"; {name} = {value:.6g}" for name, value in best.constraints.items() if value is not None))
    if not best.feasible:
        print("cosim: no evaluation met the constraints; best.ssv holds the one closest to them.", file=sys.stderr)
    say(args, f"cosim: best parameters {result.ssv}" + (f", report {result.report}" if result.report else ""))
    say(args, f"cosim: run them: {result.command}")
    return 0 if best.feasible else 1
