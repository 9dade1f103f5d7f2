"""Command line: ``greyfmu build [--out DIR] [--force] [--fmi {2,3}] [NAME...]``, ``greyfmu info [NAME]``,
``greyfmu catalogue [-o FILE]``."""

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
    info = commands.add_parser("info", help="list the FMUs, or describe one: what it is, inputs and outputs with "
                                            "units, parameters with unit, default and range, sample time, what to wire")
    info.add_argument("name", nargs="?", metavar="NAME", help="an FMU (default: list them all)")
    catalogue = commands.add_parser("catalogue", help="write the FMU catalogue as Markdown (docs/catalogue.md)")
    catalogue.add_argument("-o", "--output", metavar="FILE", help="file to write (default: standard output)")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if args.command in ("info", "catalogue"):
        return _catalogue(args)
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


def _catalogue(args: argparse.Namespace) -> int:
    """``greyfmu info [NAME]`` and ``greyfmu catalogue [-o FILE]`` (`greyfmu.catalogue`)."""
    from greyfmu.catalogue import all_names, entries, markdown, summary_text, text
    from greyfmu.names import canonical_name, unknown_message

    if args.command == "catalogue":
        page = markdown(entries())
        if args.output:
            with open(args.output, "w", encoding="utf-8") as out:
                out.write(page)
            print(f"greyfmu catalogue: {args.output}")
        else:
            sys.stdout.write(page)
        return 0
    if args.name is None:
        print(summary_text(entries()))
        return 0
    name = canonical_name(args.name, all_names())
    if name not in all_names():
        print(f"greyfmu info: {unknown_message([args.name], all_names())}", file=sys.stderr)
        return 2
    print(text(entries([name])[0]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
