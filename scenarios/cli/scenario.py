"""``vmt scenario NAME``: run a named study end to end.

``SCENARIOS`` maps a name to a function ``f(args) -> int``; add a study by
adding one entry (the lead adds the cross-pocket scenarios here).
"""

from __future__ import annotations

import math

from scenarios.cli.guard import said


def _mfb(args) -> int:
    from scenarios.mfb import closed_loop, run

    from scenarios.cli.guard import progress_line
    from scenarios.mfb import describe_budget

    from scenarios.mfb import plan_truth_spec

    spec = plan_truth_spec(args.name, args.machine, args.errors)   # None: the study's own truth machine
    kw = dict(seed=args.seed, noise_um=args.noise_um, mc_runs=500 if args.mc is None else args.mc, machine=spec)
    from scenarios.cli.options import declared_ripples

    if declared := declared_ripples(args):
        kw["declared_ripple"] = declared
    if args.bar_calibration:
        from scenarios.mfb import read_bar_calibration

        kw["bar_calibration"], kw["bar_true_m"] = read_bar_calibration(args.bar_calibration)
    if args.apply_comp and not args.comp:
        from scenarios.mfb import compensators

        compensators(args.apply_comp, args.name)  # a bad directory is refused before the campaign
    with progress_line(f"{args.name}: steps (each measurement simulated, then two of identification)") as bar:
        r = run(args.name, progress=bar, **kw)
    d = r.doc
    print(f"vmt scenario {args.name}: {d['placements']} placements, {d['measurements']} measurements, "
          f"{d['touches']} touches on {d['machine']}, {r.seconds:.1f} s; {d['model']}")
    if "collision_check" in d:
        from scenarios.mfb import describe_collision_check

        print(describe_collision_check(d["collision_check"]))
    print(f"{'error':6s} {'unit':5s} {'max|injected|':>14s} {'max|ident-inj|':>15s} {'max U95':>9s}")
    for s, e in d["errors"].items():
        inj = max(abs(v) for v in e["injected"])
        u = f"{max(e['u95']):9.3f}" if "u95" in e else f"{'n/a':>9s}"
        print(f"{s:6s} {e['unit']:5s} {inj:14.3f} {e['max_dev']:15.4f} {u}")
    print(f"max_dev_um {d['max_dev_um']:.4f}  max_dev_urad {d['max_dev_urad']:.4f}")
    if not any("u95" in e for e in d["errors"].values()):   # (it printed nan in the column)
        print("max U95 n/a: no uncertainty computed (it is with probing noise, --noise-um > 0, a bar calibration "
              "u > 0, Monte Carlo runs, --mc N, or a declared ripple; this run has none)")
    elif d.get("u95_inputs") is not None and "probing noise" not in d["u95_inputs"]:
        print(f"U95 ({d['u95_method']}) of {' and '.join(d['u95_inputs']) or 'no input (all u 0)'} alone: a "
              "noise-free run (no probing noise; the placements and the bar's calibration error not drawn)")
    if d.get("declared_ripple"):
        print("U95 includes the declared ripple (type B, unknown phase): " + ", ".join(
            f"{s} {v.get('amplitude_um', v.get('amplitude_urad')):g} {'um' if 'amplitude_um' in v else 'urad'} / "
            f"{v['period_mm']:g} mm" for s, v in d["declared_ripple"].items()))
    if d.get("u95_scope"):
        print(f"note: {d['u95_scope']}")
    if d.get("model_fit_note"):
        print(f"note: {d['model_fit_note']}")
    if d.get("between_nodes_note"):
        print(f"note: {d['between_nodes_note']}")
    if d.get("twists"):
        from scenarios.mfb import describe_twists

        print(describe_twists(d["twists"]))
    if d.get("not_compensated"):
        from scenarios.mfb import describe_not_compensated

        print(describe_not_compensated(d["not_compensated"]))
    if args.comp:
        line = None if args.comp_line_mm is None else comp_line_m(args.comp_line_mm, r)
        for p in r.write_comp(args.comp, line):
            print(f"wrote {p}")
        from scenarios.mfb import (COMP_FILES_REPLACE, compensation_range, describe_comp_line,
                                   describe_compensation_range)

        print(describe_compensation_range(compensation_range(r.plan.nodes, r.strokes_m)))
        print(f"note: {COMP_FILES_REPLACE}")
        if r.J_m is not None:
            print(f"note: {describe_comp_line(r.plan.nodes, r.J_m, line)}")
    if args.apply_comp:
        with progress_line(f"{args.name}: compensated campaigns simulated") as bar:
            loop = closed_loop(args.name, args.apply_comp, before=r, progress=bar, **kw)
        d["closed_loop"] = loop
        print(f"closed loop with {args.apply_comp}: a new campaign on the compensated virtual machine "
              f"(seed {loop['seed_after']}), identified again; um")
        print(f"{'':15s} {'axis':>4s} {'true pos. max':>13s} {'within U95':>10s} {'identified max':>14s} "
              f"{'U95 max':>8s} {'volumetric max':>14s}")
        for key in ("before", "per_axis_files", "volumetric"):
            if key not in loop:
                continue
            for a in "XYZ":
                pa = loop[key]["positioning"][a]
                u = pa["u95_max_um"]
                print(f"{key:15s} {a:>4s} {pa['true_max_um']:13.3f} {pa.get('true_within_u95', '-'):>10s} "
                      f"{pa['identified_max_um']:14.3f} {u if u is not None else float('nan'):8.3f} "
                      f"{loop[key]['volumetric_residual_um'][a]:14.3f}")
        print("(true: the exact simulator's positioning error, zero at the first node; within U95: nodes where it "
              "lies within the U95 of the identification that made the compensation; volumetric: the tip "
              "deviation over the node box, a rigid motion removed)")
        if "strokes" in loop["before"]:
            rg = loop["before"]["strokes"]["range_mm"]
            print("beyond the node box, out to the strokes (" + ", ".join(f"{a} {rg[a][0]:.0f}..{rg[a][1]:.0f}"
                                                                     for a in "XYZ") + " mm), exact, um: "
                  "true positioning max outside the nodes / inside; volumetric max over the stroke box")
            for key in ("before", "per_axis_files", "volumetric"):
                if key in loop:
                    st = loop[key]["strokes"]
                    print(f"{key:15s} " + "  ".join(
                        f"{a} {st['positioning_outside_max_um'][a]:.3f} / {st['positioning_inside_max_um'][a]:.3f}"
                        for a in "XYZ") + "; volumetric " + " ".join(
                        f"{a} {st['volumetric_residual_um'][a]:.3f}" for a in "XYZ"))
        ln = loop["before"]["on_comp_line"]["readings_mm"]
        print("on the .comp files' lines through readings " + ",".join(f"{v:g}" for v in ln) + " mm (each axis's "
              "exact error along its line, zero at the first node), max, um: " + "; ".join(
                  f"{key} " + " ".join(f"{a} {loop[key]['on_comp_line']['max_abs_um'][a]:.3f}" for a in "XYZ")
                  for key in ("before", "per_axis_files", "volumetric") if key in loop))
        print(f"volumetric error over the node box, um: {'':6s} {'axis':>4s} {'before':>7s} {'after':>7s} "
              f"{'predicted':>9s} {'U95':>6s} {'U95 added':>9s} {'within U95':>10s}  verdict")
        for key in ("per_axis_files", "volumetric"):
            for a, v in loop.get(key, {}).get("volumetric_check", {}).items():
                verdict = ("improved beyond its U95" if v["improved"] else
                           "not worse (within its U95)" if v["not_worse"] else "WORSE than its U95")
                print(f"{key:45s} {a:>4s} {v['before_max_um']:7.3f} {v['after_max_um']:7.3f} "
                      f"{v['predicted_max_um']:9.3f} {v['u95_max_um']:6.3f} {v['u95_added_max_um']:9.3f} "
                      f"{v['within_u95']:>10s}  {verdict}")
        if args.comp:
            import json as _json
            from pathlib import Path

            cj = _json.loads((Path(args.comp) / f"{args.name}-comp.json").read_text())
            part = [f"{s} {e['applied_factor']:.2f}" for s, e in cj["errors"].items() if e["applied_factor"] < 1.0]
            print("errors applied in part (the fraction that leaves the least mean-square error against its U95, "
                  "core.comprule; 0: left out): " + (", ".join(part) or "none"))
    if args.budget_runs:
        from scenarios.mfb import budget

        with progress_line(f"{args.name}: budget, pipeline runs") as bar:
            d["budget"] = budget(args.name, mc_runs=args.budget_runs, seed=args.seed, progress=bar,
                                 bar_calibration=kw.get("bar_calibration"), bar_true_m=kw.get("bar_true_m"))
        print(describe_budget(d["budget"]))
    if args.report:
        from scenarios.mfb_report import mfb_report

        with progress_line(f"{args.name}: report, % of the work") as bar:
            folder = mfb_report(args.report, d, progress=bar)
        print(f"report (index.html, figures, recording.rrd) -> {folder}")
    if args.json:
        from core.atomic import write_json_atomic

        write_json_atomic(args.json, d, special=True)
        print(f"wrote {said(args.json)}")
    return 0


def parse_comp_line_mm(text: str) -> tuple:
    """``--comp-line-mm X,Y,Z``: three finite readings, mm, else one line naming the option."""
    from core.exceptions import ConfigError

    try:
        v = tuple(float(x) for x in text.split(","))
    except ValueError:
        v = ()
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise ConfigError(f"--comp-line-mm {text!r}: expected three finite numbers X,Y,Z (readings, mm), "
                          "e.g. 0,100,-50")
    return v


def comp_line_m(text: str, r):
    """The ``--comp-line-mm`` point in m, each reading within the truth machine's stroke for the
    compensation's stylus (the lines run through the work volume), else one line naming the axis."""
    import numpy as np

    from core.exceptions import ConfigError
    from scenarios.mfb import COMP_STYLUS, STYLI

    v = np.asarray(parse_comp_line_mm(text), float)
    J = np.asarray(STYLI[COMP_STYLUS], float) / 1e-3
    for i, a in enumerate("XYZ"):
        if r.strokes_m and a in r.strokes_m:
            lo, hi = (w / 1e-3 - J[i] for w in r.strokes_m[a])
            if not lo - 1e-6 <= v[i] <= hi + 1e-6:
                raise ConfigError(f"--comp-line-mm {text}: {a} {v[i]:g} mm is beyond the machine's {a} stroke, "
                                  f"readings {lo:g}..{hi:g} mm (stylus {COMP_STYLUS}): the lines run through the "
                                  "work volume")
    return v * 1e-3


def _mfb_reversal(args) -> int:
    from scenarios.mfb import bar_calibration_doc, reversal_on_cmm

    rev = reversal_on_cmm(seed=args.seed, **({} if args.noise_um is None else {"noise_um": args.noise_um}))
    doc = bar_calibration_doc(rev)
    print(f"vmt scenario mfb-reversal: the bar as is and turned about x on a simulated CMM, {rev['repeats']} "
          f"repeats, {rev['touches']} touches (eqs 5-7); estimate - truth, um:")
    for k, v in rev["compared_um"].items():
        print(f"{k}: max {v['max_abs_um']:.3f}, U95 max {v['U95_max_um']:.3f}, within U95 {v['within_U95']}")
    if args.json:
        from core.atomic import write_json_atomic

        write_json_atomic(args.json, doc, special=True)
        print(f"bar calibration ({doc['format']}) -> {args.json} (for --bar-calibration)")
    return 0


def _cross_pocket_uncertainty(args) -> int:
    from core.atomic import write_json_atomic
    from scenarios.crosspocket import cross_pocket_uncertainty

    runs = 1000 if args.mc is None else args.mc   # checked by _dispatch
    from scenarios.cli.guard import progress_line

    with progress_line("cross-pocket-uncertainty: cases") as bar:
        r = cross_pocket_uncertainty(runs=runs, seed=args.seed, progress=bar)
    print(f"vmt scenario cross-pocket-uncertainty: {r['method']}, u_probe {r['u_probe_um']} um")
    print(f"{'C angles / deg':22s} {'spheres':8s} {'max U95(G) / um':>16s} {'linear':>8s} {'paper':>6s}")
    for c in r["cases"]:
        ang = ",".join(f"{a:g}" for a in c["c_angles_deg"])
        if not c["identifiable"]:
            print(f"{ang:22s} {str(c['spheres']):8s}  not identifiable: {c['reason']}")
            continue
        paper = "" if c["paper_g_u95_max_um"] is None else f"{c['paper_g_u95_max_um']:g}"
        print(f"{ang:22s} {str(c['spheres']):8s} {c['g_u95_max_um']:16.2f} {c['g_u95_max_linear_um']:8.2f} {paper:>6s}")
    print("Table 2 (U95, k=2):  C / deg   U_XC / um   U_YC / um   U_CC / urad   (paper)")
    for t in r["table2"]:
        print(f"{'':20s} {t['c_deg']:7g} {t['u_xc_um']:11.2f} {t['u_yc_um']:11.2f} {t['u_cc_urad']:13.2f}"
              f"   ({t['paper_u_xc_um']:g}, {t['paper_u_yc_um']:g}, {t['paper_u_cc_urad']:g})")
    for n in r["notes"]:
        print(f"note: {n}")
    if args.report:
        from scenarios.crosspocket import paper_figures, pin_circle

        figs = paper_figures(args.report, r, pin_circle(seed=args.seed), seed=args.seed)
        print(f"figures ({', '.join(figs)}) -> {args.report}")
    if args.json:
        write_json_atomic(args.json, r, special=True)
        print(f"wrote {said(args.json)}")
    return 0


def _pin_circle(args) -> int:
    from core.atomic import write_json_atomic
    from scenarios.crosspocket import pin_circle

    r = pin_circle(seed=args.seed, **({} if args.noise_um is None else {"noise_um": args.noise_um}))
    print(f"vmt scenario pin-circle: {r['pins']} pins, {r['touches']} touches at C = "
          f"{', '.join(f'{a:g}' for a in r['c_angles_deg'])} deg on {r['machine']}")
    print(f"pin position error, max: raw at C=0 {r['raw_c0_pin_error_max_um']:.2f} um -> self-calibrated "
          f"{r['selfcal_pin_error_max_um']:.2f} um (paper: {r['paper']}); aligned on pins 1 and 11, delta_L "
          f"measured {r['delta_L']['measured_um']:.2f} um (u {r['delta_L']['u_um']:.2f} um), yaw {r['yaw']}")
    if args.report:
        from pathlib import Path

        from scenarios.crosspocket import pin_figure

        print(f"report (index.html, fig17) -> {pin_figure(Path(args.report), r).parent}")
    if args.json:
        write_json_atomic(args.json, r, special=True)
        print(f"wrote {said(args.json)}")
    return 0


#: name -> runner(args) -> exit code
SCENARIOS = {
    "mfb-3axis": _mfb,
    "mfb-5axis": _mfb,
    "mfb-reversal": _mfb_reversal,
    "cross-pocket-uncertainty": _cross_pocket_uncertainty,
    "pin-circle": _pin_circle,
}


def register(sub) -> None:
    p = sub.add_parser("scenario", help="run a named study: simulate, identify, compare with the truth")
    p.add_argument("name", choices=sorted(SCENARIOS), help="scenario name")
    p.add_argument("--json", default=None, help="write the result JSON here")
    p.add_argument("--seed", type=int, default=1, help="seed of the simulated campaign")
    from scenarios.cli.options import add_machine_args, add_mc_arg, add_noise_arg

    add_noise_arg(p, "default: mfb 0.125, the MFB paper's 0.25 um at k=2; pin-circle 0.9; 0 = noise-free; "
                     "cross-pocket-uncertainty does not take it")
    add_machine_args(p, default=None, what="mfb scenarios: the truth machine, its chain the plan's (default: the "
                                            "plan's machine)",
                     errors_default="study", errors_why="the MFB studies' truth: the realistic set without the "
                                                        "screw ripple, which their smooth models represent")
    p.add_argument("--comp", default=None, metavar="DIR",
                   help="mfb scenarios: write the LinuxCNC per-axis compensation files and the vmt JSON tables here "
                        "(a .comp file replaces the joint's BACKLASH and any earlier COMP_FILE, and is right on its "
                        "axis's line through readings 0 of the other axes, or --comp-line-mm's: README "
                        "'Compensation files')")
    p.add_argument("--comp-line-mm", default=None, metavar="X,Y,Z", dest="comp_line_mm",
                   help="mfb scenarios, with --comp: the point the .comp files' lines pass through, readings "
                        "(stylus-tip centre, machine frame), mm: X.comp carries X's error along X at this Y and Z "
                        "(the Abbe terms of X's angular errors there included), Y.comp along Y at this X and Z, "
                        "Z.comp along Z at this X and Y (each file's own axis's entry unused); exact on those "
                        "lines only. Default: each file the positioning error EXX, EYY, EZZ, its line through "
                        "readings 0 (the run prints the node box's centre)")
    p.add_argument("--apply-comp", default=None, metavar="DIR", dest="apply_comp",
                   help="mfb scenarios: apply the compensation in DIR (X/Y/Z.comp as LinuxCNC does, and the "
                        "vmt-comp/1 tables as a volumetric controller) to the virtual machine, re-run, identify "
                        "again; the JSON gets closed_loop (before/after per axis)")
    p.add_argument("--report", default=None, metavar="DIR",
                   help="report folder (index.html, the paper's figures as PNG; cross-pocket-uncertainty and "
                        "the mfb scenarios also the tables and recording.rrd, pin-circle its Fig. 17); not for "
                        "mfb-reversal")
    p.add_argument("--bar-calibration", default=None, metavar="FILE", dest="bar_calibration",
                   help="mfb scenarios: identify with this bar calibration (vmt-bar-calibration/1 JSON, as "
                        "'vmt scenario mfb-reversal --json FILE' writes it) instead of the declared one; a "
                        "simulated calibration's true bar is the one simulated")
    from scenarios.cli.options import add_declared_ripple_args

    add_declared_ripple_args(
        p, "mfb scenarios: a screw ripple the machine holds and no MFB plan sees (period shorter than twice the "
           "bar's 50 mm pitch), per positioning or straightness error: amplitude um and period mm, e.g. "
           "EXX=0.4:10,EYY=0.2:10; its effect on the node tables (unknown phase) joins the U95 as a type B term",
        "mfb scenarios: the same for an angular error (a pitch or yaw ripple of the screw), amplitude urad and "
        "period mm, e.g. EBX=1:10")
    p.add_argument("--budget-runs", type=int, default=0, metavar="N", dest="budget_runs",
                   help="mfb scenarios: add the uncertainty budget (each source's share per error, and N "
                        "Monte Carlo runs of the whole pipeline with every source; about 8 s of CPU a run; "
                        "not --mc's runs: each of these simulates the campaign again and identifies it, and their "
                        "U95 is 2 x RMS, not percentiles, so 2 or more)")
    add_mc_arg(p, "default 500 for the mfb scenarios, where 0 is the linear propagation alone; 1000 for "
                  "cross-pocket-uncertainty; not for mfb-reversal, pin-circle")
    p.set_defaults(func=_dispatch)


def _dispatch(args) -> int:
    from core.exceptions import ConfigError
    from scenarios.cli.options import check_mc

    # what a study does not read: refused in one phrasing, never silently ignored
    mfb_only = tuple((opt, v, ()) for opt, v in (
        ("--machine", args.machine), ("--errors", args.errors), ("--comp", args.comp),
        ("--apply-comp", args.apply_comp), ("--bar-calibration", args.bar_calibration),
        ("--declared-ripple-um-mm", args.declared_ripple), ("--declared-ripple-urad-mm", args.declared_ripple_urad),
        ("--budget-runs", args.budget_runs or None), ("--comp-line-mm", args.comp_line_mm)))
    for opt, v, takers in mfb_only + (("--noise-um", args.noise_um, ("mfb-reversal", "pin-circle")),
                                      ("--mc", args.mc, ("cross-pocket-uncertainty",)),
                                      ("--report", args.report, ("cross-pocket-uncertainty", "pin-circle"))):
        if v is not None and args.name not in ("mfb-3axis", "mfb-5axis") + takers:
            why = " (its probing u is the paper's 1.38 um)" if args.name == "cross-pocket-uncertainty" else ""
            raise ConfigError(f"{opt}: {args.name} does not take it{why}; "
                              f"it is for {', '.join(('mfb-3axis', 'mfb-5axis') + takers)}")
    if args.comp_line_mm is not None:
        parse_comp_line_mm(args.comp_line_mm)   # refused before the campaign
        if not args.comp:
            raise ConfigError("--comp-line-mm needs --comp DIR: it says where the .comp files written there are exact")
    if args.mc is not None:
        check_mc(args.mc, zero="the linear propagation's U95 alone" if args.name.startswith("mfb-") else None)
    if args.budget_runs and args.budget_runs < 2:
        raise ConfigError(f"--budget-runs must be >= 2 (a Monte Carlo spread), got {args.budget_runs}")
    return SCENARIOS[args.name](args)
