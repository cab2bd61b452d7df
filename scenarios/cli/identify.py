"""``vmt identify LOG --json OUT``: 2D self-calibration of a probe log (core.selfcal)."""

from __future__ import annotations

from scenarios.cli.options import GRID_HELP, add_bar_calibration_arg, add_mc_arg, add_noise_arg, check_mc, parse_grid


def register(sub) -> None:
    p = sub.add_parser("identify", help="2D self-calibration on a rotary table (workpiece, X/Y and C errors); on a "
                                         "multi-feature bar's log (artefact: mfb) the 21 errors of X, Y, Z")
    p.add_argument("log", help="probe-log/1 campaign: the same targets at several C angles, or a multi-feature "
                               "bar's placements (its artefact line 'mfb': the volumetric identification, Viprey "
                               "2016; what the log must hold: docs/formats.md)")
    p.add_argument("--json", required=True, metavar="OUT", help="JSON report to write (atomically)")
    p.add_argument("--grid-mm", default=None, metavar="STEP|x0:x1:step",
                   help=GRID_HELP + " (22; not for an MFB log, whose nodes are its bars' points of interest)")
    p.add_argument("--delta-l-um", type=float, default=None,
                   help="X positioning error at the last x node, measured (eq 17); omitted = scale unknown")
    add_bar_calibration_arg(p)
    add_mc_arg(p, "default: none, the linear propagation's U95 alone; the runs draw the probing noise")
    p.add_argument("--seed", type=int, default=None,
                   help="seed of the Monte Carlo runs (0); only with --mc: without it nothing is drawn")
    add_noise_arg(p, "for U95; default: sigma from the residuals", old=("--u-probe-um",))
    p.add_argument("--tool-offset-mm", default=None, metavar="X,Y,Z",
                   help="the probe's offsets J the log was probed with, mm (spindle gauge point minus stylus-tip "
                        "centre, as a machine file's [tool] offset_mm); recorded in the state (estimate.identified_on) "
                        "so that vmt vcmm --machine-state can check its tool: the tables are the tool's X/Y deviation "
                        "with this probe, placed at reading + J. A log that records its J (its tool_offset_mm line: "
                        "vmt probe / import grbl --tool-offset-mm) is identified with that J without the option, and "
                        "another J given here is refused. Neither: recorded as unknown (null), the tables at the "
                        "readings, and vmt vcmm applies the state unchecked")
    from scenarios.cli.options import add_declared_ripple_args

    add_declared_ripple_args(
        p, "a ripple finer than the grid each table holds, from the machine's spec (e.g. a screw's pitch error: "
           "EXX=0.38:10,EYY=0.2:10; amplitude bound um, period mm; tables EXX, EYX, EXY, EYY): a sinusoid at an "
           "unknown phase in the U95 (the residuals do not show its value at the datum's nodes). Omitted: the U95 "
           "holds only the model error the residuals show. An MFB log: any translation table of X, Y, Z (as vmt "
           "scenario mfb-*)",
        "the same for the yaw table (ECY or ECX, the machine's): amplitude urad and period mm, e.g. ECY=0.15:10; an "
        "MFB log: any angular table of X, Y, Z")
    from scenarios.cli.guard import NOISE_POSITIVE

    p.set_defaults(func=run, vmt_rules=NOISE_POSITIVE)   # the sigma of the U95: > 0, -1 and 0 in one phrasing


def run(args) -> int:
    from scenarios.cli.guard import progress_line

    args.mc = 0 if args.mc is None else check_mc(args.mc, zero="none")   # before any work
    with progress_line("identify") as bar:
        return _run(args, bar)


def _run(args, bar) -> int:
    import numpy as np

    from core.exceptions import ConfigError
    from scenarios.cli.reading import read_probe
    from core.scope import check_planar_scope
    from core.selfcal import self_calibrate, yaw_for_chain
    from core.touches import from_log
    from core.uncertainty import monte_carlo_touches

    if args.seed is not None and not args.mc:  # refused, not ignored: without --mc nothing is drawn
        raise ConfigError(f"--seed {args.seed}: it seeds the Monte Carlo runs, and there are none; add --mc N")
    from scenarios.cli.options import parse_tool_offset, tool_offset_of_log, tool_offset_record

    if args.tool_offset_mm is not None:
        parse_tool_offset(args.tool_offset_mm)     # a bad value refused before any work (the commands' one parser)
    from scenarios.cli.options import declared_ripples

    declared_ripples(args)  # their form refused before any work; the tables they name once the log's kind is known
    steps = 4 if args.mc else 3
    bar(0, steps)
    log = read_probe(args.log, "identify", bar=bar)
    from core.mfblog import is_mfb_log

    if is_mfb_log(log):     # a multi-feature bar: the volumetric identification, never the planar one
        return _run_mfb(args, log, bar)
    if args.bar_calibration is not None:
        raise ConfigError(f"--bar-calibration: {args.log} is not a multi-feature bar's log (its artefact line is "
                          f"not 'mfb'): the option is for MFB logs")
    sub = _declared(args)
    # J: the log's tool_offset_mm line (the record of what was done), else --tool-offset-mm, else unknown; an
    # option that says another J than the log's is refused here, before any work and any file written
    J_mm, J_from = tool_offset_of_log(log, args.tool_offset_mm)
    warned = list(log.warnings)
    check_planar_scope(log, "identify")
    yaw = yaw_for_chain(log.meta.get("kinematic_chain"))
    other = [k for k in sub if k in ("ECY", "ECX") and k != yaw]
    if other:
        raise ConfigError(f"{args.log}: --declared-ripple-urad-mm {other[0]}: this machine's yaw table is {yaw} "
                          f"(its chain {log.meta.get('kinematic_chain')!r})")
    # the planar model takes touches with normals in XY (sphere points off the
    # equator are for 3D fits); say how many were left out
    planar = abs(log.col("nz")) <= 0.01
    t = from_log(log.select(planar))
    if not planar.all():
        bar.clear()     # the line said goes on a line of its own, not after the progress line
        from core.exceptions import counted

        print(f"{args.log}: {counted(int((~planar & log.ok).sum()), 'touch')} with normals out of the XY plane "
              "left out")
    # what the state is identified on (estimate.identified_on): a state applied elsewhere is refused by vcmm
    from scenarios.identify_report import identify_record, identify_report

    on = identify_record(log, J_mm, planar & log.ok)   # J: the log's tool_offset_mm line or --tool-offset-mm
    file_row = np.flatnonzero(planar)[t.row]           # each touch's data row in the file (0-based, as the reader)
    del log, planar  # the touches hold what the identification needs: the log's memory goes before it
    grid = parse_grid("22" if args.grid_mm is None else args.grid_mm, t.pn_R)
    dL = None if args.delta_l_um is None else args.delta_l_um * 1e-6
    sigma = None
    if args.noise_um is not None:
        sigma = args.noise_um * 1e-6
    bar(1, steps)
    from scenarios.cli.guard import about_file

    with about_file(args.log):  # 'rank deficient by 31', 'eq 6 needs ...': of this log's design
        res = self_calibrate(t, grid, dL, sigma_m=sigma, yaw=yaw, subgrid=sub or None)
        bar(2, steps)
        mc = None
        if args.mc and res.sigma_m > 0:
            mc = monte_carlo_touches(t, grid, res.sigma_m, runs=args.mc,
                                     rng=np.random.default_rng(args.seed or 0), delta_L_m=dL, yaw=yaw)
            bar(3, steps)
    from core.atomic import write_json_atomic

    report = identify_report(res, mc, on)   # the state at reading + J, with its identified_on record
    report["input_warnings"] = warned
    report["tool_offset"] = tool_offset_record(J_mm, J_from)   # the J the tables are placed with, and whence
    out = write_json_atomic(args.json, report, special=True)
    bar(steps, steps)
    bar.close()         # the report's lines below the finished progress line, not on it
    G = res.G
    print(f"{args.log}: {res.n_touches} touches, {len(G)} targets, {_setups_said(res, t)};"
          f" residual RMS {res.rms_m * 1e6:.3f} um; workpiece {G.min() * 1e6:+.2f}..{G.max() * 1e6:+.2f} um;"
          f" scale {'known' if res.scale_known else 'unknown'}")
    print(_tool_offset_said(J_mm, J_from))
    _dominant(res, t, file_row)
    ht = res.design.heights
    if ht is not None:
        print(f"touches at {len(ht.levels_m)} heights: C-axis tilt per set-up"
              + (" and the tool's Abbe terms" if ht.abbe else f" (Abbe terms left out: {ht.why})")
              + f" above Z = {ht.z_ref_m * 1e3:g} mm")
    b = res.budget
    if b is not None:
        me = ", ".join(f"{k} {v * 1e6:.3f} {'urad' if k in ('ECY', 'ECX') else 'um'}"
                       for k, v in b.components.items() if v > 0)
        dec = ", ".join(f"{k} {a * 1e6:g} {'urad' if k in ('ECY', 'ECX') else 'um'} per {p * 1e3:g} mm"
                        for k, (a, p) in sub.items())
        print(f"U95: probing sigma {b.sigma_probe_m * 1e6:.3f} um"
              + (f", model error the tables cannot follow: {me}" if me else ", no model error seen in the residuals")
              + (f"; declared sub-grid ripple: {dec}" if dec else
                 "; a ripple finer than the grid is not in it unless declared (--declared-ripple-um-mm)"))
    from core.selfcal import blind_lobes_line

    blind = blind_lobes_line(res.blind_lobes)   # what the U95 above leaves out, from the design
    if blind:
        print(blind)
    ad = report.get("not_covered", {}).get("approach_direction")
    if ad:      # residuals that follow the approach direction: a probe lobing the U95 does not cover
        print("not covered by U95: " + ad["what"])
    ce = report.get("not_covered", {}).get("correlated_errors")
    if ce and ce["significant"]:   # probing errors correlated in touch order: the U95 widened for them
        print("correlated probing errors: " + ce["what"])
    ul = report.get("not_covered", {}).get("undetected_lobes")
    if ul and not ad:
        print("not covered by U95: " + ul["what"])
    td = report.get("not_covered", {}).get("time_drift")
    if td:      # residuals that follow time: a drift inside the campaign (core.selfcal.TIME_STRUCTURE)
        print("not covered by U95: " + td["what"])
    if args.mc and mc is None:
        print("Monte Carlo skipped: no probing noise left beside the model error (sigma 0)")
    from scenarios.cli.guard import said

    print(f"wrote {said(out)}")
    return 0


#: How identify says where its J came from (scenarios.cli.options.TOOL_OFFSET_FROM).
J_FROM_WORDS = {"log": "the log's tool_offset_mm line", "log and option": "the log's tool_offset_mm line and "
                "--tool-offset-mm", "option": "--tool-offset-mm (the log has no tool_offset_mm line)"}


def _tool_offset_said(J_mm, J_from: str) -> str:
    """The line that says which probe offsets J the tables are placed with and where they came from."""
    if J_mm is None:
        return ("probe offsets J unknown (no tool_offset_mm line in the log, no --tool-offset-mm): the tables at the "
                "readings, the state's probe_offsets_J_mm null")
    return (f"probe offsets J = ({', '.join(f'{v:g}' for v in J_mm)}) mm, from {J_FROM_WORDS[J_from]}: the tables at "
            "the axis positions reading + J")


def _setups_said(res, t) -> str:
    """"4 C angles" when each set-up is at its own C angle (as before), else "4 set-ups at 1 C angle": the
    distinct C positions of the touches, to 1e-9 deg (review32d F8: 4 set-ups all at C = 0 were said to be
    "4 C angles")."""
    import numpy as np

    from core.exceptions import counted

    n = len(res.design.setup_ids)
    c = np.unique(np.round(np.degrees(np.asarray(t.rot_rad, float)[:, 2]), 9))
    return counted(n, "C angle") if c.size == n else f"{counted(n, 'set-up')} at {counted(int(c.size), 'C angle')}"


def _dominant(res, t, file_row) -> None:
    """Name the touches that dominate the residual (core.selfcal.dominant_rows; review32d F3: one reading typed
    10 mm off gave a residual RMS of 364 um and an EXY 'model error' with no row named)."""
    import numpy as np

    from core.exceptions import counted
    from core.selfcal import DOMINANT_MOST, DOMINANT_Z, dominant_rows

    dom = dominant_rows(res.residuals_m)
    if not dom.size:
        return
    r = res.residuals_m
    share = float(np.sum(r[dom] ** 2) / np.sum(r ** 2))
    rest = np.delete(r, dom)
    named = ", ".join(f"row {int(file_row[i])} (set-up {t.setup_ids[t.setup[i]]!r}, target "
                      f"{t.target_ids[t.target[i]]!r}) {r[i] * 1e6:+.1f} um" for i in dom[:DOMINANT_MOST])
    more = f" and {dom.size - DOMINANT_MOST} more" if dom.size > DOMINANT_MOST else ""
    print(f"residual dominated by {counted(int(dom.size), 'touch', 'touches')}, {'each ' * (dom.size > 1)}over "
          f"{DOMINANT_Z:g} times the "
          f"RMS of the smaller ones: {named}{more}; {100 * share:.1f} % of the residual sum of squares, the other "
          f"touches' RMS {np.sqrt(np.mean(rest ** 2)) * 1e6:.3f} um. Every figure above rests on them: check those "
          "readings (a typed value? vmt discover names such outliers)")


#: The tables a declared ripple may name, per option (the self-calibration's; the yaw is the machine's).
RIPPLE_TABLES = {"um": ("EXX", "EYX", "EXY", "EYY"), "urad": ("ECY", "ECX")}


def _declared(args) -> dict:
    """``--declared-ripple-um-mm`` / ``--declared-ripple-urad-mm`` -> ``{table: (m or rad, m)}`` or a ConfigError
    naming the option and the symbol."""
    from core import iso
    from core.exceptions import ConfigError
    from scenarios.cli.options import declared_ripples

    out = declared_ripples(args)
    for k in out:
        unit = "urad" if iso.symbol(k).angular else "um"
        if k not in RIPPLE_TABLES[unit]:
            raise ConfigError(f"--declared-ripple-{unit}-mm: {k} is not a table of the self-calibration "
                              f"(one of {', '.join(RIPPLE_TABLES[unit])})")
    return out


#: Percent of ``vmt identify``'s work on a multi-feature bar's log done when the bars' points of interest are
#: fitted and when every measurement's noise gain is computed (:func:`core.mfblog.read_mfb_log` counts them); the
#: identification's three steps share the rest evenly. Measured on ``vmt simulate mfb-3axis``'s log with --mc 500
#: (session 38, load 3-11: the line read 0/4 for the 7.5 s of the reading, then "~23 s left" of 11 s): reading
#: 7.5 s of 18 s, the identification's steps 4.4, 5.6 and 0.8 s.
MFB_IDENTIFY_SHARES = (15, 40)


def _run_mfb(args, log, bar) -> int:
    """``vmt identify`` on a multi-feature bar's log: the 21 errors of X, Y, Z (:func:`scenarios.mfb.identify_log`),
    the options the planar identification alone takes refused in one line, nothing written."""
    import numpy as np

    from core.exceptions import ConfigError
    from core.mfblog import STYLUS_COLUMN, TOOL_OFFSET_KEY, read_mfb_log

    src = args.log
    for opt, v in (("--grid-mm", args.grid_mm), ("--delta-l-um", args.delta_l_um)):
        if v is not None:
            why = {"--grid-mm": "its error tables' nodes are its bars' points of interest (its error_table_nodes_mm "
                                "line, else derived from the bars)",
                   "--delta-l-um": "the bar's calibration gives the scale"}[opt]
            raise ConfigError(f"{opt}: {src} is a multi-feature bar's log: {why}")
    from scenarios.cli.options import declared_ripples
    from scenarios.mfb import _check_declared_ripple

    declared = _check_declared_ripple(declared_ripples(args))   # (vmt scenario mfb-*'s: any motion table)
    if args.tool_offset_mm is not None:
        if log.has(STYLUS_COLUMN):
            raise ConfigError(f"--tool-offset-mm: {src} names each row's stylus (its {STYLUS_COLUMN} column and "
                              "stylus_offsets_mm line): the option is for a log of one probe")
        from dataclasses import replace

        from scenarios.cli.options import tool_offset_of_log

        J_mm, _ = tool_offset_of_log(log, args.tool_offset_mm)
        log = replace(log, meta={**log.meta, TOOL_OFFSET_KEY: ",".join(repr(float(v)) for v in J_mm)})
    cert = _bar_certificate(args)
    fitted, read = MFB_IDENTIFY_SHARES
    ml = read_mfb_log(log, cert, progress=lambda k, n: bar(fitted + (read - fitted) * k // max(n, 1), 100))
    sigma = args.noise_um * 1e-6 if args.noise_um is not None else ml.sigma_probe_m
    if sigma is None:
        raise ConfigError(f"{src}: no probing noise for the U95: give --noise-um (k = 1) or the log's "
                          "probe_repeatability_k2_um line")
    warned = list(log.warnings)
    from core.state import log_machine
    machine = log_machine(log.meta)[0]   # the plan's machine, not the controller's name, as the planar route
    del log
    from scenarios.cli.guard import about_file
    from scenarios.mfb import identify_log

    with about_file(src):   # 'rank deficient by 2 ...': of this log's plan
        doc = identify_log(ml, sigma_m=sigma, mc_runs=args.mc, rng=np.random.default_rng(args.seed or 0),
                           source=src, machine=machine,
                           progress=lambda k, n: bar(read + (100 - read) * k // max(n, 1), 100),
                           declared_ripple=declared)
    doc["input_warnings"] = warned
    from core.atomic import write_json_atomic

    out = write_json_atomic(args.json, doc, special=True)
    bar.close()
    for line in mfb_summary_lines(doc):
        print(line)
    from scenarios.cli.guard import said

    print(f"wrote {said(out)}")
    return 0


def _bar_certificate(args):
    """``--bar-calibration FILE`` (vmt-bar-calibration/1) as a :class:`core.mfblog.BarCertificate`, or None."""
    if args.bar_calibration is None:
        return None
    from core.mfblog import BarCertificate
    from scenarios.mfb import read_bar_calibration

    cal, _ = read_bar_calibration(args.bar_calibration)
    return BarCertificate(cal.E_m, cal.u_m, f"--bar-calibration {args.bar_calibration}")


def mfb_summary_lines(doc: dict) -> list[str]:
    """What ``vmt identify`` prints for an MFB log: the campaign, the model, each error's largest value and U95."""
    from core.exceptions import counted

    out = [f"{doc['log']}: multi-feature bar, {counted(doc['setups'], 'set-up')}, "
           f"{counted(doc['measurements'], 'measurement')}, {doc['touches']} touches on chain {doc['chain']}; "
           f"{doc['model']}, residual RMS {doc['rms_residual_um']:.3f} um",
           f"bar calibration from {doc['bar_calibration']}; nodes from "
           + ("the log's error_table_nodes_mm line" if doc["nodes_from"] == "log" else "the bars' points of interest")
           + f"; probing noise {doc['noise_um']:.3f} um (k = 1)",
           f"{'error':6s} {'unit':5s} {'max|identified|':>16s} {'max U95':>9s}"]
    for s, e in doc["errors"].items():
        u = f"{max(e['u95']):9.3f}" if "u95" in e else f"{'n/a':>9s}"
        out.append(f"{s:6s} {e['unit']:5s} {max(abs(v) for v in e['identified']):16.3f} {u}")
    if doc.get("u95_method"):
        out.append(f"U95: {doc['u95_method']}, of {', '.join(doc.get('u95_inputs') or ()) or 'no input'}")
    for k in ("model_fit_note", "between_nodes_note"):
        if doc.get(k):
            out.append(f"note: {doc[k]}")
    return out
