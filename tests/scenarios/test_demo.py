"""The main job: `vmt demo` tells the whole story and leaves its outputs."""

import json
import re

import numpy as np
import pytest

from core.probelog import read_probe_log
from scenarios.cli import main
from scenarios.demo import SCREW_UM


def _check_recording_frames(rrd, map_outside: str):
    """The recording read back with rerun's own reader (review30d F2): the cross pocket placed in W by
    its T_W_A (30 mm up: its mesh from W z 0, not -30 mm), the table placed in R at each set-up's C
    angle (timeline ``setup``), and each set-up's touches, taken back through that placement into W,
    on the part: the same tip centres at every set-up (float32 storage: 1e-7 m), 3 mm (the stylus
    radius) from the workpiece's nominal surface points, and inside the part's mesh in z."""
    from tests.viz.test_record import read

    pytest.importorskip("rerun.chunk")
    data = read(rrd)

    def mat(flat):                                   # rerun's Mat3x3 is column-major
        return np.asarray(flat, float).reshape(3, 3).T

    art = data["/world/R/table/W/artefact"]
    assert "Transform3D:translation" in art, "the artefact is not placed in W"
    assert np.allclose(art["Transform3D:translation"][0][0], [0.0, 0.0, 0.030], atol=1e-7)
    v = (np.asarray(art["Mesh3D:vertex_positions"][0], float) @ mat(art["Transform3D:mat3x3"][0][0]).T
         + np.asarray(art["Transform3D:translation"][0][0]))
    assert abs(v[:, 2].min()) < 1e-7                 # the part stands on W's z = 0 (the table's top)
    table, touches = data["/world/R/table"], data["/world/R/touches"]
    assert table["setup"] == touches["setup"] == [0, 1, 2, 3]
    c_deg = []
    in_W = []
    for M, tr, P in zip(table["Transform3D:mat3x3"], table["Transform3D:translation"],
                        touches["Points3D:positions"]):
        Rm = mat(M[0])
        c_deg.append(np.degrees(np.arctan2(Rm[0, 1], Rm[0, 0])))    # T_R_W = Rz(-C)
        in_W.append((np.asarray(P, float) - np.asarray(tr[0])) @ Rm)
    assert np.allclose(np.mod(c_deg, 360), [0.0, 75.0, 130.0, 210.0], atol=1e-4)
    assert [len(p) for p in in_W] == [108] * 4
    for p in in_W[1:]:
        assert np.abs(p - in_W[0]).max() < 1e-7
    wp = np.asarray(data["/world/R/table/W/workpiece/nominal"]["Points3D:positions"][0], float)
    gap = [np.min(np.linalg.norm(in_W[0] - q, axis=1)) for q in wp]
    assert np.allclose(gap, 0.003, atol=1e-7)
    assert v[:, 2].min() < in_W[0][:, 2].min() and in_W[0][:, 2].max() < v[:, 2].max()
    # the drawn deviation is the form (G with the datum's shift, rotation and scale removed, a few um),
    # labelled so: G itself is about -30 um on these walls (review30d F3)
    labels = data["/world/R/table/W/workpiece/deviation"]["Points3D:labels"][0]
    assert len(labels) == 92 and all(s.startswith("form = ") and s.endswith(" µm") for s in labels)
    # the error map's U95 (review30d F4) on its 11 x 11 nodes, rows y: 0 where eqs 16-17 fix the gauge
    # (the origin node, and (110, 0) mm with the scale), largest on the edge rows y = +-110 mm, where
    # the yaw ECY rests on one row of touches (U95 279 urad at y = -110 mm: 31 um at x = -110 mm)
    u = np.array([float(s.split()[2]) for s in data["/world/R/error_map/identified/u95"]["Points3D:labels"][0]])
    u = u.reshape(11, 11)
    assert u[5, 5] == 0.0 and u[5, 10] == 0.0
    assert set(np.unravel_index(np.argsort(u, axis=None)[-4:], u.shape)[0]) <= {0, 10}
    assert u[0, 0] > 30.0
    # and says how often the truth lies within it (session 31), the count the demo printed
    legend = data["/world/R/error_map/legend"]["TextDocument:text"][0][0]
    assert "node colour U95 (k=2). The true map lies outside the map's U95" in legend and map_outside in legend


def test_demo_end_to_end(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["demo", "--out-dir", str(out)]) == 0
    text = capsys.readouterr().out
    assert "both hidden effects named" in text
    # like with like: the identified EC0Y beside the injected one in identify's gauge
    assert "injected, in the same gauge (eqs 16-17" in text
    assert "EYY ripple 1.5 um, pitch 8 mm" in text  # what the code hides, in the words
    # like with like (review31 F12): the raw C = 0 error with what self-calibration cannot see removed, as the
    # self-calibrated one (measured 2.33 -> 0.61 um), the unremoved figure (21.69) only as such
    m = re.search(r"with what self-calibration cannot see removed from both \(the part's shift, rotation and scale "
                  r"and a common offset\): raw C=0 probing ([\d.]+) um RMS -> self-calibrated ([\d.]+) um RMS \(the "
                  r"raw C=0 touches with nothing removed: ([\d.]+) um RMS\)", text)
    assert m and float(m[2]) < float(m[1]) < float(m[3]) / 3, text
    # what the lobing biases (review31 F4): the visible part, the worst phase at the amplitude found, and the
    # hidden lobe's own shift through the same fit; no 'up to' (the visible part is no bound)
    step3 = text[text.index("3. identify"):text.index("4. discover")]
    assert "by up to" not in step3
    m = re.search(r"its visible part \(what the residuals show\) moves EC0Y by ([\d.]+) urad .*; the part the "
                  r"design absorbs adds to it: a lobe of order 2 and ~[\d.]+ um at its worst phase moves EC0Y by "
                  r"([\d.]+) urad .*\n.*the hidden 2-lobe \(1\.5 um\) alone moves EC0Y by ([\d.]+) urad", step3)
    assert m and float(m[1]) < float(m[3]) <= float(m[2]), step3     # measured 39.97 < 62.13 <= 73.27
    # the error map's U95 is not shown as if it covered (session 30: the truth outside it at 32 of 121 nodes,
    # said nowhere): the count printed, in the report and the recording alike, with why (70 of 119 measured;
    # test_demo_map_u95.py: 1 of 119 without the lobing probe, so at least 36 asked here)
    m = re.search(r"error map against the truth: outside its U95 at (\d+) of (\d+) nodes \(2 gauge nodes aside\), "
                  r"up to [\d.]+ x at \(-?\d+, -?\d+\) mm: the lobing probe's bias, which no U95 of this model holds",
                  text)
    assert m and int(m[2]) == 119 and 36 <= int(m[1]) <= 119, text
    map_outside = f"at {m[1]} of 119 nodes (2 gauge nodes, U95 0, aside)"
    log = read_probe_log(out / "cross-pocket.csv")
    assert log.n == 432 and log.ok.all()
    disc = json.loads((out / "discover.json").read_text())
    assert {f["cause"] for f in disc["findings"]} >= {"probe_lobing", "periodic_axis_error"}
    assert disc["gain"]["cv_rms_ratio"] < 0.5
    ident = json.loads((out / "identify.json").read_text())
    assert len(ident["workpiece"]) == 92 and ident["monte_carlo"]["runs"] == 1000
    mfb = json.loads((out / "mfb-3axis.json").read_text())
    assert (mfb["placements"], mfb["measurements"], len(mfb["errors"])) == (14, 17, 21)
    # its compensation applied to the machine and measured again: the true error (exact simulator)
    # falls 10x and within the U95 of the identification that made it at the nodes, as a 95 % interval
    # should: over 24 nodes the count outside is near Binomial(24, 0.05), P(>= 4) = 0.03, so at most 3
    # (a U95 half the right size would leave about 8 outside)
    loop = json.loads((out / "mfb-3axis-closed-loop.json").read_text())
    outside = 0
    for a in "XYZ":
        before, files = loop["before"]["positioning"][a], loop["per_axis_files"]["positioning"][a]
        n = len(mfb["errors"][f"E{a}{a}"]["identified"])
        k, m = (int(v) for v in files["true_within_u95"].split("/"))
        assert m == n and files["true_max_um"] < before["true_max_um"] / 10
        outside += n - k
        assert loop["volumetric"]["volumetric_residual_um"][a] < loop["before"]["volumetric_residual_um"][a] / 4
        # the volumetric error over the node box fell by more than the U95 of what the compensation leaves
        # (seed 1: X/Y/Z 44.7/19.0/11.6 -> 2.5/2.1/1.9 um against U95 2.5/1.8/3.9)
        assert loop["volumetric"]["volumetric_check"][a]["improved"], loop["volumetric"]["volumetric_check"][a]
    assert outside <= 3, outside
    assert "applied to the virtual machine" in text
    # step 7: the ISO 230-2 test of Y on step 1's nmv3000 (not step 6's VMC), its figures and discovery on it
    pos = json.loads((out / "iso230-2.json").read_text())
    iso = pos["iso230_2"]
    assert iso["E_um"] >= iso["M_um"] > 0 and iso["A_um"] >= iso["E_um"]
    assert 0.2 < pos["discover"]["noise_um"]["sigma_um"] < 0.4          # 0.3 um scatter, 40 dof
    assert (out / "positioning-Y.csv").read_text().startswith("# format: positioning-log/1")
    assert "ISO 230-2: a positioning test of the Y axis" in text
    # step 5, the hardware route (tests/scenarios/test_demo_steps37.py: its figures on three set-ups): the same
    # touches as step 2's to the contact searches' tolerance (measured 1e-8 um), so the same state
    m = re.search(r"EC0Y ([+-][\d.]+) urad against step 3's ([+-][\d.]+) \(U95 ([\d.]+)\).*the touches agree to "
                  r"(\S+) um", text)
    assert m and m[1] == m[2] and float(m[4]) < 1e-5, text
    assert float(m[3]) == round(ident["axes"]["EC0Y"]["u95_urad"], 2)       # identify.json's U95 of EC0Y
    probed = read_probe_log(out / "cross-pocket-probed.csv")
    assert probed.n == log.n and probed.ok.all() and probed.meta["source"] == "vmt probe"
    # step 8, the ISO 230-2 table's closed loop (test_demo_steps37.py says why 5x): M falls with the table
    cl = json.loads((out / "iso230-2-closed-loop.json").read_text())
    assert cl["after"]["M"] < cl["before"]["M"] / 5 and cl["before"]["E"] == pytest.approx(iso["E_um"], rel=1e-12)
    assert cl["true"]["after"]["range_at_targets_um"] < 1.5 < cl["true"]["before"]["range_at_targets_um"]
    # step 9, the virtual CMM on step 6's state: the true machine's one measurement (one noise draw) within
    # 2 U95 of the identified mean on every measurand (U95 ~ 2 u: beyond 2 U95 is ~4 u, p ~ 6e-5 for a
    # right state; a state off by its own U95 would miss by more in the face distance, measured +0.25 of 0.32)
    vc = json.loads((out / "vcmm-block.json").read_text())
    assert [r["name"] for r in vc["truth"]] == ["bore diameter", "face distance", "top flatness"]
    for r in vc["truth"]:
        assert abs(r["true_minus_mean"]) < 2 * r["U95"], r
    assert vc["vcmm"]["runs"] >= 200 and all(m["converged"] for m in vc["vcmm"]["measurands"])
    # step 10, the MFB log route: step 6's campaign as the file `vmt simulate mfb-3axis --seed 2026` writes (the
    # same bytes: the CLI run here), identified from the file alone to step 6's values (measured 1e-9 um/urad:
    # the rebuilt bar poses' rounding, 1e-15 m amplified; 1e-6 as tests/scenarios/test_mfb_log_route.py) and
    # discovered on the volumetric baseline: nothing named on a campaign with nothing beyond the model
    cli_log = tmp_path / "cli-mfb.csv"
    assert main(["simulate", "mfb-3axis", "--out", str(cli_log), "--seed", "2026"]) == 0
    assert cli_log.read_bytes() == (out / "mfb-3axis.csv").read_bytes()
    mlog = read_probe_log(out / "mfb-3axis.csv")
    assert mlog.n == mfb["touches"] and mlog.meta["artefact"] == "mfb"
    mid = json.loads((out / "mfb-3axis-identify.json").read_text())
    assert mid["format"] == "vmt-identify-mfb/1" and set(mid["errors"]) == set(mfb["errors"])
    for k, e in mfb["errors"].items():
        np.testing.assert_allclose(mid["errors"][k]["identified"], e["identified"], rtol=0, atol=1e-6, err_msg=k)
        np.testing.assert_allclose(mid["errors"][k]["u95"], e["u95_lin"], rtol=0, atol=1e-6, err_msg=k)
    m = re.search(r"every identified value within (\S+) um/urad of step 6's", text)
    assert m and float(m[1]) < 1e-6, text
    md = json.loads((out / "mfb-3axis-discover.json").read_text())
    assert md["format"] == "vmt-discover/1" and md["findings"] == [], md["findings"]
    assert md["baseline"]["model"].startswith("volumetric MFB") and md["log"] == str(out / "mfb-3axis.csv")
    assert re.search(r"\n  found: none \(", text), text
    # the closing line names every file the steps wrote, each there
    said = text.split("by step: ", 1)[1].splitlines()[0]
    named = [f for part in said.split("; ") for f in part.split(" ", 1)[1].split(", ")]
    assert len(named) >= 20 and all((out / f).is_file() for f in named), named
    # the README's figures of the demo are the ones it printed (a figure there must not drift from the demo)
    section = readme_demo_section()
    missing = [p for p in readme_demo_phrases(text, out) if p not in section]
    whole = " ".join(readme_text().split())
    missing += [p for p in readme_elsewhere_phrases(text, out) if p not in whole]
    assert not missing, missing
    # every JSON names its format (docs/formats.md), the nested reports theirs
    assert [ident["format"], disc["format"], mfb["format"], loop["format"], pos["format"], cl["format"],
            vc["format"], vc["vcmm"]["format"]] == [
        "vmt-identify/1", "vmt-discover/1", "vmt-mfb/1", "vmt-mfb-closed-loop/1", "vmt-demo-iso230-2/1",
        "vmt-demo-iso230-2-closed-loop/1", "vmt-demo-vcmm/1", "vmt-vcmm/1"]
    assert (iso["format"], pos["discover"]["format"]) == ("vmt-iso230-2/1", "vmt-discover/1")
    assert json.loads((out / "comp" / "mfb-3axis-comp.json").read_text())["format"] == "vmt-comp/1"
    for f in ("index.html", "recording.rrd", "error_map.png", "residuals_baseline.png"):
        assert (out / "report" / f).stat().st_size > 1000
    assert map_outside in (out / "report" / "index.html").read_text()
    _check_recording_frames(out / "report" / "recording.rrd", map_outside)
    # its identify.json holds the record vmt identify writes of the same log with the demo's probe offsets J
    # (the nmv3000's 150 mm tool), so vcmm refuses it on another machine as it refuses identify's: without it
    # the state applied to vmc-3axis with a notice about files older than session 26 (exit 0; review29c F2)
    rec = ident["estimate"]["identified_on"]
    assert (rec["machine"], rec["chain"], rec["probe_offsets_J_mm"]) == (
        "nmv3000", "V[w-C-A-b-Y-X-Z-(C)-t]", [[0.0, 0.0, 150.0]])
    cli = tmp_path / "id.json"
    assert main(["identify", str(out / "cross-pocket.csv"), "--json", str(cli), "--tool-offset-mm", "0,0,150",
                 "--mc", "0"]) == 0
    assert json.loads(cli.read_text())["estimate"]["identified_on"] == rec
    assert ident["tool_offset"] == {"J_mm": [0.0, 0.0, 150.0], "from": "machine"}      # whence its J, as identify's
    vcmm = ["vcmm", "--plan", "scenarios/data/vcmm-block-plan.csv", "--task", "scenarios/data/vcmm-block-task.toml",
            "--no-budget", "--machine", "vmc-3axis", "--json", str(tmp_path / "v.json"), "--machine-state"]
    for state in (out / "identify.json", cli):
        capsys.readouterr()
        assert main(vcmm + [str(state)]) == 2
        err = capsys.readouterr().err
        assert f"--machine-state {state}: identified on machine 'nmv3000'" in err and "another structure" in err
    assert not (tmp_path / "v.json").exists()


def readme_text() -> str:
    from pathlib import Path

    return (Path(__file__).resolve().parents[2] / "README.md").read_text()


def readme_demo_section() -> str:
    """README's "What `make demo` shows", its whitespace collapsed (the text wraps anywhere)."""
    return " ".join(readme_text().split("### What `make demo` shows", 1)[1].split("\n## ", 1)[0].split())


def readme_elsewhere_phrases(text: str, out) -> list[str]:
    """The demo's figures README quotes outside its demo section ("`vmt identify` on a simulated cross-pocket
    log": what the lobing biases), built from the demo's print and its identify.json."""
    hidden = re.search(r"the hidden 2-lobe \(([\d.]+) um\) alone moves EC0Y by ([\d.]+) urad", text)
    visible = re.search(r"its visible part \(what the residuals show\) moves EC0Y by ([\d.]+) urad", text)
    worst = re.search(r"at its worst phase moves EC0Y by ([\d.]+) urad", text)
    amp = re.search(r"a pre-travel lobing of order 2, ~([\d.]+) um", text)
    assert hidden and visible and worst and amp, text
    ident = json.loads((out / "identify.json").read_text())
    ecy = ident["not_covered"]["approach_direction"]["shift"]["ECY"]["worst_phase"]
    h, v, w = float(hidden[2]), float(visible[1]), float(worst[1])
    return [f"the demo's 2-lobe moves EC0Y by {h:.1f} µrad where its visible part says {v:.1f}",
            f"the demo finds {amp[1]} µm of its {hidden[1]} µm 2-lobe: EC0Y {w:.1f} µrad holds the {h:.1f}, ECY "
            f"{ecy:.1f} does not hold"]


def readme_demo_phrases(text: str, out) -> list[str]:
    """The phrases README's demo section must hold, built from what the demo printed (``text``) and wrote
    (``out``): each figure README quotes from the demo, in README's words and to its decimals."""
    def grab(pattern, n=1):
        m = re.search(pattern, text)
        assert m, pattern
        return m.groups() if n > 1 else m[1]

    f = float
    ph = []
    raw, sc, plain = grab(r"raw C=0 probing ([\d.]+) um RMS -> self-calibrated ([\d.]+) um RMS \(the raw C=0 touches "
                          r"with nothing removed: ([\d.]+) um RMS", 3)
    ph.append(f"the raw probing error at C = 0, {raw} µm RMS, becomes {sc} µm RMS (x{f(raw) / f(sc):.1f}; the raw "
              f"touches with nothing removed are {plain} µm RMS")
    k, amp = grab(r"a pre-travel lobing of order (\d), ~([\d.]+) um", 2)
    ph.append(f"(a lobing probe, order {k}, ~{amp} µm)")
    v = grab(r"moves EC0Y by ([\d.]+) urad \(([\d.]+) x its U95\), EXX by ([\d.]+) um \(([\d.]+) x its U95\)", 4)
    ph.append(f"moves EC0Y by {v[0]} µrad ({v[1]} x its U95) and EXX by {v[2]} µm ({v[3]} x)")
    v = grab(r"at its worst phase moves EC0Y by ([\d.]+) urad \(([\d.]+) x\), EXX by ([\d.]+) um \(([\d.]+) x\)", 4)
    ph.append(f"at its worst phase by {v[0]} µrad ({v[1]} x) and {v[2]} µm ({v[3]} x)")
    v = grab(r"alone moves EC0Y by ([\d.]+) urad, EXX by ([\d.]+) um", 2)
    ph.append(f"EC0Y {v[0]} µrad, EXX {v[1]} µm")
    v = grab(r"outside its U95 at (\d+) of (\d+) nodes \(2 gauge nodes aside\), up to ([\d.]+) x at \((-?\d+), (-?\d+)\)",
             5)
    ph.append(f"outside it at {v[0]} of the {v[1]} nodes the gauge leaves free (up to {v[2]} x, at ({v[3]}, {v[4]}) mm")
    v = grab(r"period ([\d.]+) mm, EYY amplitude ([\d.]+)", 2)
    ph.append(f"period {v[0]} mm, {v[1]} µm against {SCREW_UM:g} µm hidden")
    b = grab(r"baseline [^\n]*, cross-validated ([\d.]+) um\n")
    e, r = grab(r"extended [^\n]*, cross-validated ([\d.]+) um \(x([\d.]+)", 2)
    ph.append(f"cut to {r} of the baseline's ({f(b):.2f} -> {f(e):.2f} µm)")
    b, e = grab(r"workpiece against the truth: baseline ([\d.]+) um RMS -> extended ([\d.]+) um RMS", 2)
    ph.append(f"{f(b):.2f} -> {f(e):.2f} µm RMS")
    rows = re.findall(r"([XYZ]) ([\d.]+) -> ([\d.]+) \((\d+)/(\d+) nodes within U95\) -> [\d.]+ um", text)
    assert len(rows) == 3
    ph.append("from " + " / ".join(f"{f(r[1]):.1f}" for r in rows) + " µm (X, Y, Z) to "
              + " / ".join(r[2] for r in rows) + " µm, within the identification's U95 at "
              + f"{sum(int(r[3]) for r in rows)} of {sum(int(r[4]) for r in rows)} nodes")
    vol = re.findall(r"([XYZ]) ([\d.]+) -> ([\d.]+) \(predicted [\d.]+, U95 ([\d.]+);", text)
    assert len(vol) == 3
    ph.append("volumetric error over the node box from " + " / ".join(r[1] for r in vol) + " to "
              + " / ".join(r[2] for r in vol) + " µm")
    ph.append("(" + " / ".join(r[3] for r in vol) + " µm)")
    # step 5
    e1, e0, u = grab(r"EC0Y ([+-][\d.]+) urad against step 3's ([+-][\d.]+) \(U95 ([\d.]+)\)", 3)
    agree = grab(r"the touches agree to (\S+) um")
    ph.append(f"EC0Y {e1} µrad, as step 3's (U95 {u} µrad); the touches agree to {agree} µm")
    # step 8 (its JSON: the printed figures are its rounding)
    cl = json.loads((out / "iso230-2-closed-loop.json").read_text())
    b, a, t = cl["before"], cl["after"], cl["true"]
    ph.append(f"E {b['E']:.2f} -> {a['E']:.2f} µm, M {b['M']:.2f} -> {a['M']:.2f} µm (x{b['M'] / a['M']:.0f}), "
              f"A {b['A']:.2f} -> {a['A']:.2f} µm")
    ph.append(f"({b['R']:.2f} -> {a['R']:.2f} and {b['B']:.2f} -> {a['B']:.2f} µm")
    ph.append(f"falls from {t['before']['range_at_targets_um']:.2f} to {t['after']['range_at_targets_um']:.2f} µm of "
              f"range at the targets")
    ph.append(f"from {t['before']['range_um']:.2f} to {t['after']['range_um']:.2f} µm, up to "
              f"{t['after']['max_abs_um']:.2f} µm left")
    ph.append(f"targets {cl['target_gaps_mm'][0]:.0f}-{cl['target_gaps_mm'][1]:.0f} mm apart")
    ph.append(f"every {cl['true_step_mm']:g} mm, both directions")
    # step 9
    vc = json.loads((out / "vcmm-block.json").read_text())
    r = {x["name"]: x for x in vc["truth"]}
    ph.append(f"{vc['vcmm']['runs']} runs")
    ph.append(f"U95 {r['bore diameter']['U95']:.2f} µm on the bore diameter, {r['face distance']['U95']:.2f} µm on "
              f"the face distance, {r['top flatness']['U95']:.2f} µm on the top's flatness")
    inside = all(x["inside"] for x in vc["truth"])
    ph.append("measures " + ", ".join(f"{x['true_minus_mean']:+.2f}" for x in vc["truth"][:-1])
              + f" and {vc['truth'][-1]['true_minus_mean']:+.2f} µm from the identified means"
              + (", each inside its 95 % interval" if inside else ""))
    # step 10
    v = grab(r"(\d+) touches, (\d+) measurements, \d+ set-ups, (\d+) styli -> ", 3)
    ph.append(f"{v[0]} touches, {v[1]} measurements, {v[2]} styli")
    v = grab(r"baseline [^\n]*: (\d+) rows, (\d+) parameters, RMS ([\d.]+) um, noise ([\d.]+) um \(residuals, \d+ dof; "
             r"the probe's ([\d.]+)\)", 5)
    ph.append(f"{v[0]} rows, {v[1]} parameters, RMS {v[2]} µm, noise {v[3]} µm against the probe's {v[4]}")
    found = grab(r"\n  found: ([^(]+) \(").strip()
    ph.append(f"found: {found},")
    return ph


def test_lobing_text_says_which_lobes_it_cannot_see():
    """The demo's probe has 2 lobes of 1.5 um and 3 lobes of 1.17 um (4.87 um peak-to-valley); its
    four approach directions 90 deg apart cannot see the 3 lobes (discover reports k3 n/d), and the
    reported peak-to-valley (2.97 um, about 2 x 1.48) is of the 2 lobes alone. main printed
    'pre-travel varies 2.97 um peak-to-valley with the approach azimuth' as if it were the probe's."""
    from scenarios.demo import _finding_text

    f = {"cause": "probe_lobing", "params": {"k1_amplitude_um": None, "k2_amplitude_um": 1.48,
                                             "k3_amplitude_um": None, "k4_amplitude_um": 0.06,
                                             "pretravel_variation_pv_um": 2.97}}
    assert _finding_text(f) == ("pre-travel varies 2.97 um peak-to-valley with the approach azimuth "
                                "(of the lobes this design determines; k = 3 not determined)")
    f["params"]["k3_amplitude_um"] = 1.2
    assert _finding_text(f) == "pre-travel varies 2.97 um peak-to-valley with the approach azimuth"


def test_finding_text_of_a_magnitude_the_design_cannot_see():
    """A periodic error's amplitude whose pair has a coefficient the data cannot see is None in the report
    (session 22); the demo's text formatted it with ':.2f' and stopped with a TypeError (the session 22 review,
    on gen_a periodic_axis_error 1025's report). It says "not determined"; a value keeps its U95."""
    from scenarios.demo import _finding_text

    f = {"cause": "periodic_axis_error", "params": {"axis": "X", "period_mm": 18.69, "EXX_amplitude_um": None},
         "params_u95": {"period_mm": 0.05, "EXX_amplitude_um": None}}
    assert _finding_text(f) == "axis X, period 18.69 mm, EXX amplitude not determined"
    f["params"]["EXX_amplitude_um"], f["params_u95"]["EXX_amplitude_um"] = 1.47, 0.09
    assert _finding_text(f) == "axis X, period 18.69 mm, EXX amplitude 1.47 +/- 0.09 um (U95)"
    f = {"cause": "probe_lobing", "params": {"pretravel_variation_pv_um": None}}
    assert _finding_text(f) == "pre-travel varies with the approach azimuth (its peak-to-valley not determined)"


def test_raw_error_like_the_self_calibrated_one():
    """Review31 F12: the demo compared 21.7 um of raw error with nothing removed to 0.61 um with the part's shift,
    rotation, scale and a common offset removed. Known answer: raw touches that are the true form plus exactly
    such a gauge pattern (50 um: shift, rotation, scale, offset) plus a repeat's +-e (averaged per target): the
    like-for-like figure is the repeats' zero to rounding (1e-12 um asked, on values of ~50 um), the unremoved
    one the pattern's own RMS; set-up 1's touches are not read."""
    from types import SimpleNamespace

    from core.design import example_cross_pocket
    from core.selfcal import workpiece_gauge_basis
    from scenarios.demo import _raw_error_m, _Truth

    w, wn, ids = example_cross_pocket()
    rng = np.random.default_rng(5)
    g_true = rng.normal(0, 1e-6, len(ids))
    B = workpiece_gauge_basis(w, wn)
    pattern = B @ rng.normal(0, 1, B.shape[1])
    pattern *= 50e-6 / np.abs(pattern).max()
    n = len(ids)
    target = np.r_[np.arange(n), np.arange(n), np.arange(n)]          # two repeats at set-up 0, one at set-up 1
    e = np.r_[np.full(n, 0.2e-6), np.full(n, -0.2e-6), np.zeros(n)]
    dq = np.r_[g_true + pattern, g_true + pattern, np.full(n, 1.0)] + e
    t = SimpleNamespace(setup=np.r_[np.zeros(2 * n, int), np.ones(n, int)], dq_m=dq, target=target,
                        target_ids=list(ids))
    truth = _Truth({k: g for k, g in zip(ids, g_true)}, {k: p for k, p in zip(ids, w)},
                   {k: v for k, v in zip(ids, wn)})
    plain, form = _raw_error_m(t, truth, 0)
    assert form < 1e-18
    assert plain == pytest.approx(np.sqrt(np.mean(pattern ** 2) + 0.2e-6 ** 2), rel=1e-12, abs=0)
    assert plain > 10e-6


def test_lobe_bias_figures_against_the_campaign_without_the_lobe(monkeypatch, tmp_path):
    """Review31 F4: identify's note on the demo said the lobing 'biases EC0Y by up to 40 urad' (the
    structure's visible part); the demo's campaign simulated again without its 2-lobe (the 3-lobe kept,
    which the design absorbs into EXC/EYC: EC0Y as without any lobe), the same noise draws, moves EC0Y by
    62.1 urad. Known answers, from that re-simulation:
    - the demo's own figure for the hidden lobe (scenarios.demo._lobe_shift: the lobe through the fit's
      linear gain) is the re-simulated difference, every parameter to 1e-9 of the largest (measured 7e-12:
      the simulator adds the pre-travel to each touch along its normal, so the two differ by rounding);
    - the visible part is short of it (39.97): it is no bound, and the note no longer says 'up to';
    - the worst-phase figure at the amplitude found (73.27) holds it (the 62.1 within it); for ECY it does
      not (108.3 against 129.7; ECC 2.84 against 3.34): the amplitude found is 1.24 um against 1.5 injected, so the note calls it a
      bound only as good as that amplitude; with the injected amplitude it holds every block (|g . c| <=
      |g| |c|)."""
    import scenarios.demo as D
    from core.selfcal import Grid, self_calibrate

    class _Quiet:
        def __call__(self, *a, **k):
            pass

    def campaign(lobing, tmp):
        monkeypatch.setattr(D, "LOBING_M", lobing)
        machine, probe, errs = D._machine(2026, _Quiet())
        return D._campaign(machine, probe, 2026, tmp, _Quiet())[3]

    full = D.LOBING_M
    assert full[0][0] == 2
    grid = Grid.regular(-0.110, 0.110, 0.022)
    t0 = campaign(full[1:], tmp_path)
    t = campaign(full, tmp_path)
    res, res0 = self_calibrate(t, grid), self_calibrate(t0, grid)
    des, s = res.design, res.design.slices
    true = res.theta - res0.theta                                  # what the 2-lobe does, by re-simulation
    ec0y = float(true[s["EC0Y"]][0]) * 1e6
    assert ec0y == pytest.approx(62.1, abs=0.1)
    lin = D._lobe_shift(t, des, grid, 2, *full[0][1:])
    assert np.abs(true - lin).max() < 1e-9 * np.abs(lin).max()
    rep = res.to_report()["not_covered"]["approach_direction"]
    sh = rep["shift"]
    assert rep["lobe_order"] == 2 and "up to" not in rep["what"] and "visible part" in rep["what"]
    assert "the part the design absorbs is not seen and adds to it" in rep["what"]
    assert abs(sh["EC0Y"]["largest"]) < 0.7 * ec0y                  # the visible part: 39.97, no bound
    assert sh["EC0Y"]["worst_phase"] >= ec0y                       # 73.27: the 62.1 within it
    ecy = np.abs(true[s["ECY"]]).max() * 1e6
    assert sh["ECY"]["worst_phase"] < ecy                           # 108.3 < 129.7: the amplitude found is short
    a_true = float(np.hypot(*full[0][1:])) * 1e6
    for b, v in sh.items():
        largest = np.abs(lin[s[b]]).max() * 1e6
        assert v["worst_phase"] * a_true / rep["amplitude_um"] >= largest * (1 - 1e-6), b
