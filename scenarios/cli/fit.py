"""``vmt fit plane|sphere|circle|cylinder LOG``: a feature of a probe log, its form and U95."""

from __future__ import annotations

#: Format of the JSON ``vmt fit --json`` writes.
FIT_FORMAT = "vmt-fit/1"
FORM = {"plane": "flatness", "sphere": "sphericity", "circle": "roundness", "cylinder": "cylindricity"}


def register(sub) -> None:
    from core.features import KINDS

    p = sub.add_parser("fit", help="fit a plane, sphere, circle (XY) or cylinder to a log: form and U95")
    p.add_argument("kind", choices=KINDS, help="the feature")
    p.add_argument("log", help="probe-log/1 campaign (vmt probe, vmt import, vmt simulate)")
    p.add_argument("--feature", help="use only the rows of this feature (column 'feature')")
    p.add_argument("--setup", help="use only the rows of this set-up")
    p.add_argument("--json", metavar="OUT", help="also write the result, with each touch's residual, as JSON")
    p.set_defaults(func=run)


def _v(x, nd=6):
    return "(" + ", ".join(f"{c:.{nd}f}" for c in x) + ")"


def run(args) -> int:
    from core.atomic import json_safe, write_json_atomic
    from core.features import fit_log_feature
    from core.probelog import read_probe_log

    log = read_probe_log(args.log)
    r = fit_log_feature(log, args.kind, feature=args.feature, setup=args.setup)
    v = r.values
    sel = "".join(f", {k} {w}" for k, w in (("feature", args.feature), ("setup", args.setup)) if w)
    print(f"{r.kind}: {r.n} touches{sel}, stylus radius {r.stylus_r_mm:g} mm applied")
    if r.kind == "plane":
        print(f"  point {_v(v['point_mm'], 4)} mm, normal {_v(v['normal'])}")
    elif r.kind == "cylinder":
        print(f"  axis point {_v(v['point_mm'], 4)} mm, axis {_v(v['axis'])}, "
              f"radius {v['radius_mm']:.4f} mm ({v['side']})")
    else:
        print(f"  centre {_v(v['centre_mm'], 4)} mm, radius {v['radius_mm']:.4f} mm ({v['side']})")
    print("  U95 (Student t, %d dof): " % r.dof + ", ".join(f"{k} {u:.3g}" for k, u in r.u95.items()))
    print(f"  {FORM[r.kind]} {r.form_um:.3f} um (peak-to-valley about the least-squares {r.kind}, "
          f"probing noise included), rms {r.rms_um:.3f} um")
    if args.json:
        tg = log.col("target")[r.rows].astype(str).tolist()
        rep = {"format": FIT_FORMAT, "log": str(args.log), "kind": r.kind, "n": r.n, "feature": args.feature, "setup": args.setup,
               "values": v, "u95": r.u95, "form": FORM[r.kind], "form_um": r.form_um, "rms_um": r.rms_um,
               "dof": r.dof, "stylus_r_mm": r.stylus_r_mm,
               "touches": [{"row": int(i), "target": t, "residual_um": float(e)}
                           for i, t, e in zip(r.rows, tg, r.residuals_um)]}
        write_json_atomic(args.json, json_safe(rep), special=True)
        print(f"wrote {args.json}")
    return 0
