"""Named studies composing sim, core, hardware and viz; home of the ``vmt`` CLI.

Importing this package asks for one BLAS thread (:func:`one_blas_thread`)
before numpy loads, so every entry point gets it: the ``vmt`` console script,
``python -m scenarios.cli`` and the studies run as ``python -m scenarios.<study>``
(``mfb_coverage``, ``selfcal_coverage``, ... : README, docs/formats.md), which
Python imports through this package first (review31d F14: before, only the
CLI package set it, and a study's ``--workers 2`` ran 2 BLAS threads in each
process on a 2-core machine).
"""

from __future__ import annotations

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
    console script, ``python -m scenarios.cli`` and ``python -m
    scenarios.<study>`` all import it first; the variables also reach the
    studies' worker processes). Setting any of :data:`THREAD_VARS`
    (``OMP_NUM_THREADS=2 vmt bench``) overrides the default: then none is
    touched. A program that imported numpy before this package keeps the
    thread count numpy chose.
    """
    if any(environ.get(v, "").strip() for v in THREAD_VARS):
        return False
    for v in THREAD_VARS:
        environ[v] = "1"
    return True


one_blas_thread()
