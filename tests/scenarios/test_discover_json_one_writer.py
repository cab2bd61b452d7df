"""One writer of a discovery's JSON (session 37, left37): ``vmt discover`` and the demo's discover.json.

The demo wrote the engine's report alone (``d.to_report()`` and the log), without the figures ``vmt discover``
adds beside it (``workpiece_u95_gauge_free``: the workpiece's U95 outside the part's gauge, the figure
``core.discover.WORKPIECE_U95_GROWTH_WITHHELD`` judges; the form change; the lobes the baseline absorbs), so the
two files of one campaign differed. Both now come from ``scenarios.discover_run.discover_json``.

The campaign: the shipped regression study's cross pocket (0.3 um noise, its 8 mm screw ripple, seed 1), in which
discovery names the ripple, so the gauge-free figure exists (it is None without a finding).
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

STUDY = Path(__file__).resolve().parents[2] / "scenarios/data/regress-discover-nmv3000.toml"


@functools.lru_cache(maxsize=None)
def _campaign():
    import tempfile

    from core.probelog import write_probe_log
    from scenarios.regress import _cross_pocket, loads_study

    st = loads_study(STUDY.read_text(), "s.toml", "scenarios/data")
    *_, log = _cross_pocket(st, 1)
    d = Path(tempfile.mkdtemp(prefix="left37_"))
    p = d / "campaign.csv"
    write_probe_log(p, log)
    return p


def test_vmt_discover_writes_through_the_one_writer(tmp_path):
    """run_discover's file is discover_json's document of the same discovery, key for key."""
    from scenarios.discover_run import _discover_probe_log, discover_json, run_discover

    p = _campaign()
    run_discover(str(p), str(tmp_path / "d.json"))
    got = json.loads((tmp_path / "d.json").read_text())
    want = json.loads(json.dumps(discover_json(_discover_probe_log(str(p), None, None), str(p), [])))
    assert got == want
    assert got["findings"] and "workpiece_u95_gauge_free" in got


def test_the_demos_discover_json_has_what_vmt_discovers_has(tmp_path):
    """The demo's step 4 on the same campaign: its discover.json holds ``workpiece_u95_gauge_free`` (fails before:
    absent) and every key ``discover_json`` writes, equal to it for the demo's own discovery."""
    from core.discover import discover
    from core.probelog import read_probe_log
    from core.touches import from_log
    from scenarios import demo
    from scenarios.discover_run import discover_json

    p = _campaign()
    t = from_log(read_probe_log(p))

    class Truth:   # the demo scores the workpiece against its truth: the subject here is the file
        @staticmethod
        def rms_m(g, ids):
            return 0.0

    said = []
    say = type("Say", (), {"__call__": lambda self, s: said.append(s), "within": lambda self, d, n: None,
                           "wrote": lambda self, *paths: None})()
    demo._discover(t, Truth, p, tmp_path, say)
    got = json.loads((tmp_path / "discover.json").read_text())
    want = json.loads(json.dumps(discover_json(discover(t), p)))
    assert "workpiece_u95_gauge_free" in got
    assert got == want
