"""Command line: ``ctmm list`` and ``ctmm run NAME [--quick] [--output DIR]``."""
from __future__ import annotations

import argparse
import sys
from typing import Sequence

from . import scenario
from .errors import ModelError


def _summary_line(name: str, summary: dict) -> str:
    parts = [name]
    if "max_error" in summary:
        parts.append(f"max error {summary['max_error']:.3g}" if isinstance(summary["max_error"], float)
                     else f"max error {summary['max_error']}")
    if "wall_time_s" in summary:
        parts.append(f"TMM wall time {summary['wall_time_s']:.3g} s")
    if "reference_wall_time_s" in summary:
        parts.append(f"reference {summary['reference_wall_time_s']:.3g} s")
    for png in summary.get("figures", []):
        parts.append(f"plot {png}")
    return " | ".join(parts)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``ctmm`` console command."""
    parser = argparse.ArgumentParser(prog="ctmm", description="ctmm scenarios")
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("list", help="list the scenarios")
    run = sub.add_parser("run", help="run scenarios and write PNG + JSON")
    run.add_argument("names", nargs="+", metavar="NAME", help="scenario name(s) or 'all'")
    run.add_argument("--output", default="results", help="output folder (default: results)")
    run.add_argument("--quick", action="store_true", help="shorter version (smoke test)")
    args = parser.parse_args(argv)
    if args.command == "list":
        for name, module in scenario.available().items():
            print(f"{name:28s} {getattr(module, 'DESCRIPTION', '')}")
        for name, error in scenario.broken().items():
            print(f"{name:28s} (cannot be imported: {error})", file=sys.stderr)
        return 0
    names = list(scenario.available()) if args.names == ["all"] else args.names
    status = 0
    for name in names:
        try:
            summary = scenario.run_scenario(name, args.output, quick=args.quick)
        except ModelError as exc:
            print(f"ctmm: {exc}", file=sys.stderr)
            status = 2
            continue
        print(_summary_line(name, summary))
    return status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
