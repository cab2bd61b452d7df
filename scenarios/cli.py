"""The ``vmt`` command line: one entry point for the scenarios and the core.

Each sub-command lives in its own module (listed in ``COMMANDS``) exposing
``register(subparsers)``; heavy imports happen inside the command, so
``vmt --help`` stays fast. Any :class:`core.exceptions.VmtError` becomes one
line on stderr and exit status 2, never a traceback.
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
    ("iso230-2", "scenarios.cmd_iso230_2"),
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


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
