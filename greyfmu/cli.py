"""Command line: ``greyfmu build [--out DIR] [--force] [--fmi {2,3}] [NAME...]``."""

from __future__ import annotations

import argparse
import sys

from greyfmu.build import DEFAULT_OUT_DIR, BuildError, UnknownFmuError, build_fmus, fmu_names
from greyfmu.fmi3 import fmi3_name
from greyfmu.loader import cross_compiler_notices


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="greyfmu", description="greyfmu tools")
    commands = parser.add_subparsers(dest="command", required=True)
    build = commands.add_parser("build", help="build the FMUs of fmus/ (FMI 2.0 Co-Simulation <Name>.fmu; FMI 3.0 "
                                "<Name>3.fmu on demand)")
    build.add_argument("names", nargs="*", metavar="NAME",
                       help="FMUs to build, e.g. PID (FMI 2.0) or PID3 (FMI 3.0) (default: all of --fmi's versions)")
    build.add_argument("--fmi", action="append", choices=("2", "3"),
                       help="with no NAME, the FMI versions to build: 2 (<Name>.fmu, the default) and/or 3 (<Name>3.fmu)")
    build.add_argument("--out", metavar="DIR", default=DEFAULT_OUT_DIR, help=f"output folder (default: {DEFAULT_OUT_DIR})")
    build.add_argument("--force", action="store_true", help="rebuild FMUs that are up to date")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        names = args.names or None
        if names is None and args.fmi:
            names = [name for version in sorted(set(args.fmi)) for name in fmu_names()
                     for name in ([name] if version == "2" else [fmi3_name(name)])]
        paths = build_fmus(names, args.out, args.force, echo=print)
    except UnknownFmuError as error:
        print(f"greyfmu build: {error}", file=sys.stderr)
        return 2
    except BuildError as error:
        print(f"greyfmu build: {error}", file=sys.stderr)
        return 1
    print(f"{len(paths)} FMU(s) in {args.out}")
    for notice in cross_compiler_notices():
        print(notice, file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
