"""The ``vmt`` command line: one entry point for the scenarios and the core.

Each sub-command lives in its own thin module of this package (listed in
``COMMANDS``: ``scenarios/cli/<name>.py``, ``import_.py`` for ``import``)
exposing ``register(subparsers)``; the work itself is library code in core,
sim, hardware and the studies of ``scenarios``. Heavy imports happen inside
the command, so
``vmt --help`` stays fast. Any :class:`core.exceptions.VmtError` becomes one
line on stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys

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

    p = argparse.ArgumentParser(
        prog="vmt",
        description="vmt: a virtual machine-tool testbed for touch-trigger metrology.",
    )
    p.add_argument("--version", action="version", version=f"vmt {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    for _name, mod in COMMANDS:
        importlib.import_module(mod).register(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    from core.exceptions import VmtError

    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        rc = args.func(args)
    except VmtError as e:
        print(f"vmt {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"vmt {args.command}: interrupted", file=sys.stderr)
        return 130
    return int(rc or 0)
