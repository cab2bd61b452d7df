"""vmt scenario mfb-3axis: simulate -> points of interest -> 21 errors -> JSON."""

import json

import pytest


def test_cli_json_keys_and_the_compensation_closes_the_loop(tmp_path):
    """--comp writes LinuxCNC files and vmt-comp/1; --apply-comp applies them to the
    virtual machine (LinuxCNC's per-joint compensation as its motion controller
    does it, and a volumetric controller with the 21 tables), runs a new campaign
    (new noise and placements, the same bar) and identifies again.

    Closed-loop criterion (issue 14): the compensated machine's true positioning
    error (the exact simulator's) lies within the U95 of the identification the
    compensation came from, at every node of every axis. What is left is that
    identification's error (probing noise 0.125 um, bar calibration, placements)
    plus the controller's linear interpolation of the 5 mm lines (< 10 nm). The
    issue's bug (a tool-side axis doubled) cannot pass: this machine's X and Y are
    table-side, Z tool-side, and all three must come down by > 20x."""
    from scenarios.cli import main

    out = tmp_path / "mfb.json"
    comp = tmp_path / "comp"
    assert main(["scenario", "mfb-3axis", "--json", str(out), "--seed", "2", "--mc", "0", "--comp", str(comp),
                 "--apply-comp", str(comp)]) == 0
    d = json.loads(out.read_text())
    for k in ("placements", "measurements", "touches", "errors", "max_dev_um", "max_dev_urad", "closed_loop"):
        assert k in d
    assert d["placements"] == 14 and d["measurements"] == 17 and d["touches"] > 3000
    assert d["noise_um"] == pytest.approx(0.125) and len(d["errors"]) == 21
    for e in d["errors"].values():
        assert {"injected", "identified", "u95"} <= set(e)
    # the files: LinuxCNC TYPE 0 (nominal, forward, reverse, mm, ascending, at
    # most 256 lines), nominal = joint position of the reference stylus T0
    # (reading + 150 mm on Z), forward = reverse
    import numpy as np

    for a, off in zip("XYZ", (0.0, 0.0, 150.0)):
        t = np.loadtxt(comp / f"{a}.comp")
        assert t.shape[1] == 3 and len(t) <= 256 and np.all(np.diff(t[:, 0]) > 0)
        assert np.array_equal(t[:, 1], t[:, 2])
        assert t[0, 0] == pytest.approx(d["errors"][f"E{a}{a}"]["nodes_mm"][0] + off, abs=1e-6)
    j = json.loads((comp / "mfb-3axis-comp.json").read_text())
    assert j["format"] == "vmt-comp/1" and len(j["errors"]) == 21 and "ISO 230-1" in j["sign_convention"]
    assert "end_point_slope_urad" in j["errors"]["EXY"]
    loop = d["closed_loop"]
    for a in "XYZ":
        before = loop["before"]["positioning"][a]["true_max_um"]
        assert before > 9.0  # EXX 35 um, EYY 17.5 um, EZZ 10 um on this machine
        for key in ("per_axis_files", "volumetric"):
            p = loop[key]["positioning"][a]
            n = len(d["errors"][f"E{a}{a}"]["nodes_mm"])
            assert p["true_within_u95"] == f"{n}/{n}", (key, a, p)
            assert p["true_max_um"] < before / 20, (key, a, p)
    # the volumetric table removes far more than positioning: the exact tip
    # deviation over the node box (rigid motion removed), before -> after
    v0, v1 = loop["before"]["volumetric_residual_um"], loop["volumetric"]["volumetric_residual_um"]
    assert v1["rms"] < v0["rms"] / 5


def test_unknown_scenario_exit_2(capsys):
    from scenarios.cli import main

    with pytest.raises(SystemExit) as e:
        main(["scenario", "nope"])
    assert e.value.code == 2


@pytest.mark.parametrize("on_nodes,tol_um,tol_urad", [
    # errors the node tables represent exactly (C2 splines through the truth at
    # the nodes, continued along the end tangent as the tables are): what is
    # left is the model's own truncation (the touch model agrees with sim to
    # <= 13 nm per point of interest), amplified by the weakest combination
    # (relative singular value 3.4e-3). Measured 0.003 um / 0.029 urad; ~3x margin.
    (True, 0.01, 0.1),
    # the default realistic machine (profiles on 9 knots over each stroke, not
    # at the nodes): the tables' interpolation between the nodes at the holes
    # and their tangent continuation over the end rods (<= 34 mm). Measured
    # 0.074 um (EZY) / 0.154 urad (EBY), straightness against the end-point
    # line. The bounds are the issue 6 targets, 0.1 um / 0.5 urad.
    (False, 0.1, 0.5),
])
def test_noise_free_identification_matches_injected(on_nodes, tol_um, tol_urad):
    from scenarios.mfb import run

    d = run("mfb-3axis", noise_um=0.0, mc_runs=0, on_nodes=on_nodes).doc
    assert d["max_dev_um"] < tol_um and d["max_dev_urad"] < tol_urad, (d["max_dev_um"], d["max_dev_urad"])


def test_u95_covers_the_truth_and_is_useful():
    # probing noise (0.25 um k=2), the bar's true geometry off its calibration
    # by a draw of u_cal, and each placement off by a draw of U_PLACE (roll
    # included), two seeds: 252 identified values (error tables at the nodes
    # and squarenesses, the values pinned by the conventions left out).
    # Coverage: the linear U95 (= 2 u) must hold the error of >= 90 % of them
    # (95 % expected; 90 % leaves ~3.6 binomial sigma for 252 values, and the
    # noise-free truncation, 0.074 um / 0.15 urad, is well inside the bands).
    # Measured 99.2 % (97.4 % over seeds 11-14, 504 values).
    # Not trivially wide: the RMS of error / U95 above 1/3 (0.5 for a calibrated
    # band; measured 0.35 on these seeds, 0.46 over seeds 11-14), and the bands
    # themselves small: max U95 over all nodes 2.1 um positioning, 4.3 um
    # straightness, 15.8 urad angular, 8.7 urad squareness (medians 0.8 um,
    # 1.3 um, 5.0 urad, 4.9 urad); bounds 3 / 5 um, 20 / 12 urad. (With nodes
    # spanning every touch and one diagonal per plane they reached 47 um and
    # 110 urad.)
    import numpy as np

    from core import iso
    from core import volumetric as vol
    from scenarios.mfb import run

    z, U = [], {}
    for seed in (11, 12):
        r = run("mfb-3axis", seed=seed, mc_runs=0)
        d, u = r.result.design, r.unc.U95_lin
        idx = [i for s in vol.MOTION + vol.SQUARENESS for i in range(d.slices[s].start, d.slices[s].stop) if u[i] > 0]
        z.append((r.result.theta - r.truth)[idx] / u[idx])
        for s in vol.MOTION + vol.SQUARENESS:
            U.setdefault(iso.symbol(s).kind.value, []).extend(u[d.slices[s]] * 1e6)
    z = np.concatenate(z)
    assert len(z) >= 250
    assert np.mean(np.abs(z) <= 1.0) >= 0.90
    assert np.sqrt(np.mean(z ** 2)) > 1.0 / 3.0
    bound = {"positioning": 3.0, "straightness": 5.0, "angular": 20.0, "location": 12.0}
    assert set(U) == set(bound)
    for k, b in bound.items():
        assert max(U[k]) < b, (k, max(U[k]))


def test_5axis_cli_noise_free(tmp_path):
    # vmt scenario mfb-5axis: the Mikron UCP710 (table C on A, linear axes on
    # the tool), 17 measurements using A and C, the rotary axes' errors
    # injected too. Noise-free on the realistic machine: measured 0.070 um
    # (EZY) / 0.126 urad (ECZ); bounds the issue 6 targets 0.1 um / 0.5 urad.
    from scenarios.cli import main

    out = tmp_path / "mfb5.json"
    assert main(["scenario", "mfb-5axis", "--json", str(out), "--noise-um", "0", "--mc", "0"]) == 0
    d = json.loads(out.read_text())
    assert d["machine"] == "mikron-ucp710" and d["measurements"] == 17 and d["placements"] == 13
    assert len(d["errors"]) == 21
    assert d["max_dev_um"] < 0.1 and d["max_dev_urad"] < 0.5, (d["max_dev_um"], d["max_dev_urad"])


def test_5axis_compensation_closes_the_loop(tmp_path):
    """The Mikron's X, Y, Z all carry the tool: the axes whose files the old
    convention doubled. Both controllers bring the true positioning error within
    the identification's U95 at every node (criterion and margins as for the
    3-axis test)."""
    from scenarios.cli import main

    out, comp = tmp_path / "mfb5.json", tmp_path / "comp"
    assert main(["scenario", "mfb-5axis", "--json", str(out), "--mc", "0", "--comp", str(comp),
                 "--apply-comp", str(comp)]) == 0
    d = json.loads(out.read_text())
    loop = d["closed_loop"]
    for a in "XYZ":
        before = loop["before"]["positioning"][a]["true_max_um"]
        assert before > 8.0
        n = len(d["errors"][f"E{a}{a}"]["nodes_mm"])
        for key in ("per_axis_files", "volumetric"):
            p = loop[key]["positioning"][a]
            assert p["true_within_u95"] == f"{n}/{n}" and p["true_max_um"] < before / 10, (key, a, p)
    assert loop["volumetric"]["volumetric_residual_um"]["rms"] < loop["before"]["volumetric_residual_um"]["rms"] / 5
