"""The ``vmt`` command line: one entry point for the scenarios and the core.

Each sub-command lives in its own module (listed in ``COMMANDS``) exposing
``register(subparsers)``; heavy imports happen inside the command, so
``vmt --help`` stays fast. Any :class:`core.exceptions.VmtError` or
operating-system error becomes one line on stderr and exit status 2, never a
traceback, and a failed run leaves no output (:mod:`scenarios.guard`).
"""

from __future__ import annotations

import argparse
import importlib
import sys

#: (name, module) of every sub-command, in the order ``--help`` lists them.
COMMANDS = [
    ("check", "scenarios.cmd_check"),
    ("demo", "scenarios.cmd_demo"),
    ("bench", "scenarios.bench"),
    ("view", "scenarios.cmd_view"),
    ("probe", "scenarios.cmd_probe"),
    ("import", "scenarios.cmd_import"),
    ("machine", "scenarios.cmd_machine"),
    ("simulate", "scenarios.cmd_simulate"),
    ("discover", "scenarios.cmd_discover"),
    ("scenario", "scenarios.cmd_scenario"),
    ("identify", "scenarios.cmd_identify"),
    ("design", "scenarios.cmd_design"),
]


def build_parser() -> argparse.ArgumentParser:
    from core import __version__

    from scenarios.guard import OneLineParser

    p = OneLineParser(
        prog="vmt",
        description="vmt: a virtual machine-tool testbed for touch-trigger metrology.",
    )
    p.add_argument("--version", action="version", version=f"vmt {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    for _name, mod in COMMANDS:
        importlib.import_module(mod).register(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    """Run one command; every error is one line on stderr and exit status 2 (:mod:`scenarios.guard`)."""
    from scenarios.guard import run_command

    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    return run_command(args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
