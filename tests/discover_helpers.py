"""The discovery idiom the tests repeat: a campaign's touches searched with the log's own chain and columns.

``discovered(log)`` stands for the lines many tests wrote out::

    t = from_log(log)
    d = discover(t, chain=log.meta.get("kinematic_chain"), extra=extra_columns(log, t.row))

(the same call :func:`scenarios.hidden.run_campaign` and ``vmt discover`` make). ``t`` is given when the
test holds or changes the touches itself; other keywords go to :func:`core.discover.discover` as they are.
``core.discover.discover`` is looked up at each call, so a test that replaces it still reaches its stand-in.
"""

from __future__ import annotations

import core.discover as D
from core.baseline import extra_columns
from core.touches import from_log


def discovered(log, t=None, **kw):
    """:func:`core.discover.discover` on ``t`` (``from_log(log)`` if not given), with the log's
    ``kinematic_chain`` and its extra columns (:func:`core.baseline.extra_columns`) at ``t``'s rows."""
    if t is None:
        t = from_log(log)
    return D.discover(t, chain=log.meta.get("kinematic_chain"), extra=extra_columns(log, t.row), **kw)
