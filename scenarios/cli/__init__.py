"""The ``vmt`` command line: one entry point for the scenarios and the core.

Each sub-command lives in its own thin module of this package (listed in
``COMMANDS``: ``scenarios/cli/<name>.py``, ``import_.py`` for ``import``)
exposing ``register(subparsers)``; the work itself is library code in core,
sim, hardware and the studies of ``scenarios``. Heavy imports happen inside
the command, so
``vmt --help`` stays fast. Any :class:`core.exceptions.VmtError` or
operating-system error becomes one line on stderr and exit status 2, never a
traceback, and a failed run leaves no output: :func:`main` runs every command
through :func:`scenarios.cli.guard.run_command`, the one place that keeps
these promises.
"""

from __future__ import annotations

import argparse
import importlib

#: (name, module) of every sub-command, in the order ``--help`` lists them.
COMMANDS = [
    ("check", "scenarios.cli.check"),
    ("demo", "scenarios.cli.demo"),
    ("bench", "scenarios.cli.bench"),
    ("view", "scenarios.cli.view"),
    ("probe", "scenarios.cli.probe"),
    ("import", "scenarios.cli.import_"),
    ("plan", "scenarios.cli.plan"),
    ("fit", "scenarios.cli.fit"),
    ("machine", "scenarios.cli.machine"),
    ("simulate", "scenarios.cli.simulate"),
    ("discover", "scenarios.cli.discover"),
    ("scenario", "scenarios.cli.scenario"),
    ("identify", "scenarios.cli.identify"),
    ("design", "scenarios.cli.design"),
    ("iso230-2", "scenarios.cli.iso230_2"),
]


def build_parser() -> argparse.ArgumentParser:
    from core import __version__

    from scenarios.cli.guard import OneLineParser

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
    """Run one command; every error is one line on stderr and exit status 2 (:mod:`scenarios.cli.guard`)."""
    from scenarios.cli.guard import run_command

    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    return run_command(args)
