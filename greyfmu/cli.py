"""Command line: ``greyfmu build [--out DIR] [--force] [NAME...]``."""

from __future__ import annotations

import argparse
import sys

from greyfmu.build import DEFAULT_OUT_DIR, BuildError, UnknownFmuError, build_fmus
from greyfmu.loader import cross_compiler_notices


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="greyfmu", description="greyfmu tools")
    commands = parser.add_subparsers(dest="command", required=True)
    build = commands.add_parser("build", help="build the FMUs of fmus/ (FMI 2.0 Co-Simulation, pythonfmu)")
    build.add_argument("names", nargs="*", metavar="NAME", help="FMUs to build (default: all)")
    build.add_argument("--out", metavar="DIR", default=DEFAULT_OUT_DIR, help=f"output folder (default: {DEFAULT_OUT_DIR})")
    build.add_argument("--force", action="store_true", help="rebuild FMUs that are up to date")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        paths = build_fmus(args.names or None, args.out, args.force, echo=print)
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
