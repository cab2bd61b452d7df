"""core.state: the ``vmt-estimate/1`` block written and read back, and its bad input."""

import json

import numpy as np
import pytest

from core.state import StateFileError, estimate_doc, loads_estimate, read_estimate


def _doc():
    """EXX on 3 nodes (given out of order), EC0Y, and one parameter of the identification alone."""
    names = ["EXX@x=100mm", "EXX@x=-100mm", "EXX@x=0mm", "EC0Y", "G[P1]"]
    symbols = ["EXX", "EXX", "EXX", "EC0Y", None]
    at = [0.1, -0.1, 0.0, None, None]
    units = ["um", "um", "um", "urad", "um"]
    theta = np.array([2e-6, -1e-6, 0.0, 5e-6, 3e-6])
    A = np.arange(25, dtype=float).reshape(5, 5) * 1e-7
    cov = A @ A.T + np.eye(5) * 1e-14
    return estimate_doc(names, symbols, at, units, theta, cov, method="test", interpolation="linear",
                        conventions=["EXX(x=0mm)=0"]), theta, cov


def test_round_trip_orders_the_table_and_keeps_the_joint_covariance():
    doc, theta, cov = _doc()
    st = loads_estimate(json.loads(json.dumps(doc)))
    x, idx = st.tables["EXX"]
    np.testing.assert_array_equal(x, [-0.1, 0.0, 0.1])
    np.testing.assert_allclose(st.mean[idx], [-1e-6, 0.0, 2e-6], rtol=1e-12)
    assert st.mean[st.constants["EC0Y"]] == pytest.approx(5e-6, rel=1e-12, abs=0)
    keep = [1, 2, 0, 3]   # the machine parameters in the state's order; G left out
    np.testing.assert_allclose(st.factor @ st.factor.T, cov[np.ix_(keep, keep)], rtol=1e-9, atol=1e-22)
    kind, nodes, v = st.functions()["EXX"]
    assert kind == "linear" and list(v * 1e6) == pytest.approx([-1.0, 0.0, 2.0])
    assert st.conventions == ("EXX(x=0mm)=0",)


def test_a_draw_has_the_estimate_and_covariance_in_distribution(rng):
    """2e4 draws: the sample mean within 5 standard errors, the sample covariance within 5 % (its
    relative standard error at n = 2e4 is about 1 %)."""
    doc, theta, cov = _doc()
    st = loads_estimate(doc)
    d = np.array([st.draw(rng) for _ in range(20000)])
    keep = [1, 2, 0, 3]
    se = np.sqrt(np.diag(cov)[keep] / len(d))
    assert np.all(np.abs(d.mean(axis=0) - theta[keep]) < 5 * se)
    np.testing.assert_allclose(np.cov(d.T), cov[np.ix_(keep, keep)], rtol=0.05, atol=0.05 * cov.max())


def _mutate(f):
    doc, _, _ = _doc()
    doc = json.loads(json.dumps(doc))
    f(doc)
    return doc


@pytest.mark.parametrize("change, match", [
    (lambda d: d.update(format="vmt-estimate/9"), "estimate: missing"),
    (lambda d: d.update(interpolation="akima"), "interpolation"),
    (lambda d: d.update(values=d["values"][:-1]), "values: expected 5"),
    (lambda d: d.update(covariance=d["covariance"][:-1]), "covariance: expected 5 x 5"),
    (lambda d: d["covariance"][0].__setitem__(1, 1e9), "not symmetric"),
    (lambda d: d.update(covariance=(-np.eye(5)).tolist()), "not positive semi-definite"),
    (lambda d: d["values"].__setitem__(0, float("nan")), "not finite"),
    (lambda d: d["parameters"][0].update(symbol="EQQ"), "unknown ISO"),
    (lambda d: d["parameters"][3].update(unit="um"), "EC0Y is in urad"),
    (lambda d: [p.update(symbol=None) for p in d["parameters"][:2]], "a table needs >= 2 nodes"),
    (lambda d: d["parameters"][0].update(at_mm="x"), "at_mm"),
    (lambda d: [p.update(symbol=None) for p in d["parameters"]], "no machine error"),
])
def test_bad_estimates_are_refused_by_name(change, match):
    with pytest.raises(StateFileError, match=match):
        loads_estimate(_mutate(change))


def test_files_a_result_without_estimate_and_not_json(tmp_path):
    p = tmp_path / "r.json"
    p.write_text('{"method": "x"}')
    with pytest.raises(StateFileError, match="no vmt-estimate/1 estimate"):
        read_estimate(p)
    p.write_text("{")
    with pytest.raises(StateFileError, match="not JSON"):
        read_estimate(p)
    with pytest.raises(StateFileError, match="no such machine state"):
        read_estimate(tmp_path / "missing.json")


def _at_readings_doc():
    """A state written by a writer that did not know J (``positions`` POSITIONS_READINGS): EXX on X nodes,
    EXY on Y nodes, gauge words at the readings, a z range (a 2D self-calibration's state)."""
    from core.state import POSITIONS_READINGS, identified_on

    names = ["EXX@x=-100mm", "EXX@x=0mm", "EXX@x=100mm", "EXY@y=-50mm", "EXY@y=50mm", "EC0Y"]
    symbols = ["EXX", "EXX", "EXX", "EXY", "EXY", "EC0Y"]
    at = [-0.1, 0.0, 0.1, -0.05, 0.05, None]
    units = ["um"] * 5 + ["urad"]
    theta = np.array([-1e-6, 0.0, 2e-6, 0.0, 3e-6, 5e-6])
    A = np.arange(36, dtype=float).reshape(6, 6) * 1e-7
    cov = A @ A.T + np.eye(6) * 1e-14
    doc = estimate_doc(names, symbols, at, units, theta, cov, method="test at the readings", interpolation="linear",
                       conventions=["EXX(x=0mm)=0", "EXY(y=-50mm)=0", "EXC,total(C0)=0", "EXX(x=100mm)=0: scale"],
                       positions=POSITIONS_READINGS)
    doc["identified_on"] = identified_on("m", "V[w-C-Y-b-X-Z-(C)-t]", None, (27.0, 27.0))
    return doc


def test_a_state_placed_at_the_axis_positions_says_so_and_saves_and_reads_back_as_itself():
    """at_axis_positions moves the nodes by J and every label with them: the gauge's positions in
    ``conventions`` (reading + J, as a writer that knew J writes them), a note naming the J, and
    ``positions`` when saved (state_doc); saved and read back, the same state. Before session 29 the
    conventions kept the readings (EXX(x=0mm)=0 for a table whose node 0 had moved to 40 mm)."""
    from core.state import POSITIONS, POSITIONS_READINGS, state_doc

    st = loads_estimate(_at_readings_doc(), source="r.json")
    assert st.at_readings
    placed = st.at_axis_positions((0.040, -0.010, 0.150))
    np.testing.assert_allclose(placed.tables["EXX"][0], [-0.06, 0.04, 0.14], atol=1e-15)
    np.testing.assert_allclose(placed.tables["EXY"][0], [-0.06, 0.04], atol=1e-15)
    assert placed.conventions == ("EXX(x=40mm)=0", "EXY(y=-60mm)=0", "EXC,total(C0)=0", "EXX(x=140mm)=0: scale",
                                  "nodes placed at the axis positions reading + J with the reader's probe offsets "
                                  "J = (40, -10, 150) mm (the writer did not know J)")
    assert not placed.at_readings and placed.identified_on == st.identified_on
    # saved and read back: the same state, labelled axis positions
    doc = json.loads(json.dumps(state_doc(placed)))
    assert doc["positions"] == POSITIONS and doc["method"] == "test at the readings"
    back = loads_estimate(doc, source="r.json")
    assert not back.at_readings and back.conventions == placed.conventions
    assert back.identified_on == placed.identified_on and back.source == placed.source
    assert set(back.tables) == set(placed.tables) and back.constants == placed.constants
    for s, (x, idx) in placed.tables.items():
        np.testing.assert_allclose(back.tables[s][0], x, rtol=0, atol=1e-12)   # m: at_mm rounded to 1e-9 mm
        np.testing.assert_array_equal(back.tables[s][1], idx)
    np.testing.assert_array_equal(back.mean, placed.mean)
    np.testing.assert_allclose(back.factor @ back.factor.T, placed.factor @ placed.factor.T, rtol=1e-9, atol=1e-22)
    assert back.at_axis_positions((0.040, -0.010, 0.150)) is back          # placed once, not again
    # a state still at the readings saves as such, and reads back to be placed the same way
    doc_r = json.loads(json.dumps(state_doc(st)))
    assert doc_r["positions"] == POSITIONS_READINGS
    again = loads_estimate(doc_r, source="r.json").at_axis_positions((0.040, -0.010, 0.150))
    assert again.conventions == placed.conventions
    for s, (x, _) in placed.tables.items():
        np.testing.assert_allclose(again.tables[s][0], x, rtol=0, atol=1e-12)
