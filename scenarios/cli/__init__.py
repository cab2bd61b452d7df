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

# The one-BLAS-thread default (issue 19) is set when the ``scenarios`` package is imported, before this one:
# every entry point, the studies' ``python -m scenarios.<study>`` too (review31d F14). Re-exported here.
from scenarios import THREAD_VARS, one_blas_thread  # noqa: F401

#: glibc's own environment variables for the allocator settings
#: :func:`keep_freed_memory` makes (read by glibc when the process starts).
MALLOC_VARS = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "MALLOC_TOP_PAD_")

#: (mallopt parameter, value): M_MMAP_THRESHOLD (-3) 64 MiB, M_TRIM_THRESHOLD
#: (-1) 256 MiB, M_TOP_PAD (-2) 64 MiB; the numbers are glibc's <malloc.h>.
MALLOPT = ((-3, 64 << 20), (-1, 256 << 20), (-2, 64 << 20))


def keep_freed_memory(environ=os.environ, libc=None) -> bool:
    """Let glibc's allocator keep freed memory for reuse; True when this set it.

    numpy's temporaries of a few MB (discover's designs, tables and
    products) are above glibc's default mmap threshold, so each is mapped
    fresh and returned to the system when freed: about 11,000 minor page
    faults in one ``discover`` of the demo, 7-12 % of its time. With
    :data:`MALLOPT` (arrays up to 64 MiB from the heap, free heap kept up
    to 256 MiB, grown 64 MiB at a time) freed blocks are reused; peak
    resident memory stays what the largest live arrays need. A no-op
    off glibc (musl, macOS, Windows) or when the user chose: any of
    :data:`MALLOC_VARS` set, or ``GLIBC_TUNABLES`` naming a
    ``glibc.malloc`` tunable, leaves the allocator alone. ``libc``: the
    C library (tests pass a stand-in); default: this process's, on glibc.
    """
    if any(environ.get(v, "").strip() for v in MALLOC_VARS) or "glibc.malloc." in environ.get("GLIBC_TUNABLES", ""):
        return False
    if libc is None:
        import platform

        if platform.libc_ver()[0] != "glibc":
            return False
        import ctypes

        try:
            libc = ctypes.CDLL(None)
            libc.mallopt  # noqa: B018 - present on glibc; absent means not glibc after all
        except (OSError, AttributeError):
            return False
    return all([libc.mallopt(p, v) == 1 for p, v in MALLOPT])


keep_freed_memory()

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
