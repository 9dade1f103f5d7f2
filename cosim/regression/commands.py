"""``cosim compare`` and ``cosim verify``: the comparison engine on the command line.

Exit status: 0 every signal within tolerance, 1 a signal (or an experiment) fails, 2 the
input is wrong (a file unreadable, a signal missing, an FMU without reference experiments).
``--report X.html`` writes the difference report (`cosim.regression.report`) and X.png beside it.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from . import CSV_COMPARE_TOLERANCE, MODES


def add_commands(sub) -> None:
    """The ``compare`` and ``verify`` subcommands of the ``cosim`` parser."""
    compare = sub.add_parser("compare", help="check a result against a reference within tolerances: a tube in "
                                             "value and time (exit 1 if a signal leaves it)")
    compare.add_argument("reference", help="reference result (CSV or Parquet); the run is checked at its time points")
    compare.add_argument("candidate", help="result (CSV or Parquet) to check")
    compare.add_argument("--rtol", type=float, default=1e-6, help="relative band: rtol·|reference| (default 1e-6)")
    compare.add_argument("--atol", type=float, default=1e-9,
                         help="absolute floor of the band, for signals near zero (default 1e-9); the band is the "
                              "wider of the two")
    compare.add_argument("--time-tolerance", type=float, default=0.0, metavar="SECONDS",
                         help="half-width of the tube in time: an event may move by up to SECONDS (default 0)")
    compare.add_argument("--signals", nargs="+", metavar="GLOB", help="signals to compare (default: all of the "
                                                                       "reference's)")
    compare.add_argument("--tolerance", action="append", default=[], metavar="GLOB=RTOL,ATOL[,TIME]",
                         help="tolerances of the signals matching GLOB, e.g. 'plant.y=1e-6,1e-9' or "
                              "'valve.*=1e-3,1e-6,0.1' (repeatable; the most specific match wins)")
    compare.add_argument("--mode", choices=MODES, default="tube",
                         help="tube (default): the tolerances above; csv-compare: csv-compare's tube of one relative "
                              "--csv-tolerance; fmi-cross-check: the FMI cross-check rule (±10 %% of the range, max/min "
                              "of 21 of 1000 resampled points, at most 10 %% of the samples outside)")
    compare.add_argument("--on", choices=["reference", "candidate"],
                         help="tube mode: check the run at the reference's time points (default) or its own samples")
    compare.add_argument("--csv-tolerance", type=float, default=CSV_COMPARE_TOLERANCE,
                         help=f"csv-compare mode: its --tolerance (default {CSV_COMPARE_TOLERANCE})")
    compare.add_argument("--report", metavar="HTML", help="write the difference report there (and a PNG beside it)")
    compare.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help=argparse.SUPPRESS)

    verify = sub.add_parser("verify", help="run the FMI-LS-REF reference experiments an FMU carries and compare "
                                           "(exit 1 if one fails)")
    verify.add_argument("fmu", help="the FMU (its extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml)")
    verify.add_argument("--report", metavar="HTML", help="on failure, write the difference report there "
                                                         "(default: <FMU name>.verify.html in the current folder)")
    verify.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help=argparse.SUPPRESS)


def _report_path(text: str, inputs: list[str], option: str) -> Path:
    from ..record.outputs import check_output

    path = Path(text)
    return check_output(path, {Path(p).resolve() for p in inputs}, what="report", option=option,
                        suffixes=(".html", ".htm"), companions=[path.with_suffix(".png")], owner="the compared")


def compare_command(args) -> int:
    from ..record.results import read, select
    from .engine import compare
    from .report import write_report
    from .tolerances import parse_tolerance

    report = _report_path(args.report, [args.reference, args.candidate], "--report") if args.report else None
    reference, candidate = read(args.reference), read(args.candidate)
    signals = select([n for n in reference.dtype.names if n != "time"], args.signals) if args.signals else None
    tolerances = dict(parse_tolerance(text) for text in args.tolerance)
    verdicts = compare(reference, candidate, signals=signals, tolerances=tolerances, rtol=args.rtol, atol=args.atol,
                       time=args.time_tolerance, mode=args.mode, on=args.on, tolerance=args.csv_tolerance)
    for v in verdicts:
        print(f"  {'ok  ' if v.passed else 'DIFF'} {v.describe()}")
    failed = [v for v in verdicts if not v.passed]
    print(f"cosim: {len(verdicts) - len(failed)} of {len(verdicts)} signals within tolerance ({args.mode})")
    if report is not None:
        page, png = write_report(verdicts, report, title=f"{Path(args.candidate).name} against "
                                                         f"{Path(args.reference).name}")
        print(f"cosim: difference report: {page}" + (f" (plot {png})" if png.exists() else ""))
    return 1 if failed else 0


def verify_command(args) -> int:
    from ..safeio import temporary_folder
    from .lsref import summary, verify
    from .report import write_report

    report = _report_path(args.report, [args.fmu], "--report") if args.report else None
    with temporary_folder("cosim-verify-") as folder:
        outcomes = verify(args.fmu, Path(folder))
    for line in summary(outcomes):
        print(f"cosim: {line}" if not line.startswith("  ") else line)
    failed = [o for o in outcomes if not o.passed]
    if failed:
        verdicts = [v for o in failed for v in o.verdicts]
        if verdicts:
            report = report or _report_path(f"{Path(args.fmu).stem}.verify.html", [args.fmu], "--report")
            page, _ = write_report(verdicts, report, title=f"cosim verify {Path(args.fmu).name}: "
                                                           + ", ".join(o.experiment.name for o in failed))
            print(f"cosim: difference report: {page}")
    print(f"cosim: {Path(args.fmu).name}: {len(outcomes) - len(failed)} of {len(outcomes)} reference experiment(s) "
          "passed")
    return 1 if failed else 0


COMMANDS = {"compare": compare_command, "verify": verify_command}
