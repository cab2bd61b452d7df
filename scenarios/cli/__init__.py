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
import functools
import importlib
import os

#: The environment variables that size the BLAS/OpenMP thread pools (OpenBLAS
#: bundled with numpy and scipy, MKL, OpenMP), read once when the library loads.
THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def one_blas_thread(environ=os.environ) -> bool:
    """Ask for one BLAS thread unless the user chose a count; True when this set it.

    vmt's linear algebra is small and dense (discover's factorisations, the
    Monte Carlo, the identification's blocks): on a shared 2-core machine a
    threaded BLAS runs it 3-64x slower (issue 19). This must run before numpy
    is first imported, so it runs when this package is imported (the ``vmt``
    console script and ``python -m scenarios.cli`` both import it first).
    Setting any of :data:`THREAD_VARS` (``OMP_NUM_THREADS=2 vmt bench``)
    overrides the default: then none is touched.
    """
    if any(environ.get(v, "").strip() for v in THREAD_VARS):
        return False
    for v in THREAD_VARS:
        environ[v] = "1"
    return True


one_blas_thread()

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
    ("regress", "scenarios.cli.regress"),
    ("vcmm", "scenarios.cli.vcmm"),
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


@functools.cache
def _parser() -> argparse.ArgumentParser:
    """The parser, built once per process: argparse does not change it while parsing, and
    building it (13 sub-commands, 180 options) costs more than most commands' checks."""
    return build_parser()


def main(argv: list[str] | None = None) -> int:
    """Run one command; every error is one line on stderr and exit status 2 (:mod:`scenarios.cli.guard`)."""
    from scenarios.cli.guard import run_command

    parser = _parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    return run_command(args)
