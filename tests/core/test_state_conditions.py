"""core.state: when and at what temperature a state was identified (review33a F8, session 34).

``identified_on`` may carry ``t_s`` (first, last touch, s from the campaign's start) and ``temperature_C``
(per ``temp_<name>_C`` sensor: min, mean, max over the touches used); a record without them (written before
session 34) reads as before, and a state applied to touches whose sensor reads more than
``TEMPERATURE_NOTICE_C`` off gets a notice."""

import json

import numpy as np
import pytest

from core.exceptions import ConfigError
from core.probelog import make_log
from core.state import (TEMPERATURE_NOTICE_C, describe_conditions, estimate_doc, identified_on, loads_estimate,
                        log_conditions, state_doc, temperature_notice)


def _doc(rec):
    names = ["EXX@x=-100mm", "EXX@x=0mm", "EXX@x=100mm", "EC0Y"]
    cov = np.diag([1.0, 1.0, 1.0, 4.0]) * 1e-14
    d = estimate_doc(names, ["EXX"] * 3 + ["EC0Y"], [-0.1, 0.0, 0.1, None], ["um"] * 3 + ["urad"],
                     np.array([1e-6, 0.0, -1e-6, 2e-6]), cov, method="test", interpolation="linear",
                     conventions=["EXX(x=0mm)=0"])
    if rec is not None:
        d["identified_on"] = rec
    return json.loads(json.dumps(d))


def _log(temps, t_s, status=None):
    """Four touches of a plane; ``temps`` {column: 4 values}."""
    n = 4
    cols = {"setup": ["s1"] * n, "target": [f"p{i}" for i in range(n)], "t_s": t_s,
            "X_mm": [0.0, 10.0, 0.0, 10.0], "Y_mm": [0.0, 0.0, 10.0, 10.0], "Z_mm": [0.001] * n,
            "Xn_mm": [0.0, 10.0, 0.0, 10.0], "Yn_mm": [0.0, 0.0, 10.0, 10.0], "Zn_mm": [0.0] * n,
            "nx": [0.0] * n, "ny": [0.0] * n, "nz": [1.0] * n, **temps}
    if status is not None:
        cols["status"] = status
    return make_log(cols)


def test_log_conditions_known_answer_and_the_touches_used():
    log = _log({"temp_spindle_C": [20.0, 20.5, 21.0, 23.5], "temp_bed_C": [19.0, 19.0, 19.5, 19.5]},
               [0.0, 60.0, 120.0, 3600.0], status=["ok", "ok", "ok", "no_trigger"])
    c = log_conditions(log)   # the ok touches: the fourth is left out
    assert c["t_s"] == (0.0, 120.0)
    assert c["temperature_C"] == {"temp_spindle_C": (20.0, 20.5, 21.0), "temp_bed_C": (19.0, 19.0 + 1 / 6, 19.5)}
    every = log_conditions(log, np.ones(4, bool))
    assert every["t_s"] == (0.0, 3600.0) and every["temperature_C"]["temp_spindle_C"] == (20.0, 21.25, 23.5)
    # a log without sensors: no temperature (None, so the record leaves the key out)
    plain = log_conditions(_log({}, [0.0, 1.0, 2.0, 3.0]))
    assert plain == {"t_s": (0.0, 3.0), "temperature_C": None}
    assert "temperature_C" not in identified_on("m", None, **plain)


def test_round_trip_of_the_conditions_and_an_old_record_reads_as_before():
    rec = identified_on("vmc-3axis", "V[w-X-Y-b-Z-(C)-t]", [[0.0, 0.0, 150.0]], (27.0, 27.0),
                        t_s=(0.0, 4210.5), temperature_C={"temp_spindle_C": (20.1, 20.4, 20.9)})
    assert rec["t_s"] == [0.0, 4210.5] and rec["temperature_C"] == {"temp_spindle_C": [20.1, 20.4, 20.9]}
    st = loads_estimate(_doc(rec))
    assert st.identified_on == rec
    again = loads_estimate(json.loads(json.dumps(state_doc(st))))   # saved and read back: the same record
    assert again.identified_on == rec
    assert describe_conditions(st) == (f"{st.source}: identified at temp_spindle_C 20.4 C (20.1..20.9); touches "
                                       "over 4210 s of its campaign (t_s 0..4210.5 s)")
    # a record written before session 34: no t_s, no temperature; read, saved and read again unchanged
    old = {"machine": "nmv3000", "chain": "V[w-C-A-b-Y-X-Z-(C)-t]", "probe_offsets_J_mm": None, "z_mm": [27.0, 27.0]}
    st_old = loads_estimate(_doc(dict(old)))
    assert st_old.identified_on == old
    assert state_doc(st_old)["identified_on"] == old
    assert describe_conditions(st_old) is None and temperature_notice(st_old, {"temp_spindle_C": (25, 25, 25)}) is None
    assert loads_estimate(_doc(None)).identified_on is None


@pytest.mark.parametrize("key, value, match", [
    ("t_s", [5.0, 1.0], "identified_on.t_s"),
    ("t_s", [0.0], "identified_on.t_s"),
    ("t_s", "0..5", "identified_on.t_s"),
    ("temperature_C", {"temp_a_C": [21.0, 20.0, 22.0]}, "identified_on.temperature_C"),
    ("temperature_C", {"temp_a_C": [20.0, 21.0]}, "identified_on.temperature_C"),
    ("temperature_C", [20.0, 20.0, 20.0], "identified_on.temperature_C"),
    ("temperature_C", {"temp_a_C": [20.0, "x", 22.0]}, "identified_on.temperature_C"),
])
def test_bad_conditions_are_refused_by_name(key, value, match):
    rec = {"machine": "m", "chain": None, "probe_offsets_J_mm": None, "z_mm": None, key: value}
    with pytest.raises(ConfigError, match=match):
        loads_estimate(_doc(rec))


def test_temperature_notice_when_the_sensor_reads_off_and_not_otherwise():
    rec = identified_on("m", None, t_s=(0.0, 100.0), temperature_C={"temp_spindle_C": (20.0, 20.2, 20.4)})
    st = loads_estimate(_doc(rec))
    off = 20.2 + TEMPERATURE_NOTICE_C + 0.3
    note = temperature_notice(st, {"temp_spindle_C": (off, off, off)})
    assert note is not None and "identified at temp_spindle_C 20.2 C, applied to touches at 21.5 C" in note
    assert f"more than {TEMPERATURE_NOTICE_C:g} C apart" in note
    near = 20.2 + 0.9 * TEMPERATURE_NOTICE_C
    assert temperature_notice(st, {"temp_spindle_C": (near, near, near)}) is None
    assert temperature_notice(st, {"temp_bed_C": (30.0, 30.0, 30.0)}) is None   # no sensor in common
    assert temperature_notice(st, None) is None
