"""``vmt fit plane|sphere|circle|cylinder LOG``: a feature of a probe log, its form and U95."""

from __future__ import annotations

#: Format of the JSON ``vmt fit --json`` writes.
FIT_FORMAT = "vmt-fit/1"
FORM = {"plane": "flatness", "sphere": "sphericity", "circle": "roundness", "cylinder": "cylindricity"}

#: CPU seconds per line of the log read (core.probelog.read_probe_log) and of the fit once read, for the
#: progress line's share of each: measured on the MFB campaign (5,372 rows) and copies of it of 53,720 and
#: 214,880 rows, 16 us a line read; the fit a fixed 0.12 s (importing core.features 0.03 s, the first Student t of
#: the U95 0.1 s; 0.55 s while that imported scipy.stats, before session 25), a sphere or plane adding 2 us a row.
READ_S_PER_LINE, FIT_S = 16e-6, 0.12


def register(sub) -> None:
    from core.features import KINDS

    p = sub.add_parser("fit", help="fit a plane, sphere, circle (XY) or cylinder to a log: form and U95")
    p.add_argument("kind", choices=KINDS, help="the feature")
    p.add_argument("log", help="probe-log/1 campaign (vmt probe, vmt import, vmt simulate)")
    p.add_argument("--feature", help="use only the rows of this feature (column 'feature')")
    p.add_argument("--setup", help="use only the rows of this set-up")
    p.add_argument("--json", metavar="OUT", help="also write the result, with each touch's residual, as JSON")
    from scenarios.cli.options import add_stylus_r_arg

    add_stylus_r_arg(p, "default: the log's stylus_r_mm (column, else metadata); required when the log has "
                        "none; given, it wins over the log's (a qualified, effective radius)")
    p.set_defaults(func=run)


def _fitted(log, args, fit_log_feature):
    """The fit of ``args.kind`` to the log's rows; a cylinder whose axis the touches leave open says
    what the command can do about it (the library's advice, ``pass axis_hint``, is no option of it)."""
    from core.exceptions import ConfigError, FitError
    from core.features import MixedRows, NoStylusRadius, mixed_rows_text
    from scenarios.cli.options import no_stylus_r

    try:
        return fit_log_feature(log, args.kind, feature=args.feature, setup=args.setup,
                               stylus_r_mm=args.stylus_r_mm)
    except MixedRows as e:      # the library names its keywords; the command names its options
        raise ConfigError(f"{args.log}: {mixed_rows_text(e.spans)}; choose one with "
                          + " and ".join(f"--{c} NAME" for c in e.spans)) from None
    except NoStylusRadius:
        raise no_stylus_r(f"{args.log}: says no stylus radius (no stylus_r_mm column or metadata)") from None
    except FitError as e:
        said = str(e)
        if not said.endswith("; pass axis_hint"):
            raise
        said = said[: -len("; pass axis_hint")]
        raise FitError(said + ("; fit one cylinder's touches: --feature NAME" if args.feature is None else
                               "; these touches do not fix a cylinder's axis (it takes touches "
                               "around it at two or more heights)")) from None


def _radius_from(r) -> str:
    """Where the applied stylus radius came from, and what the log says when the option overrode it."""
    if r.stylus_r_source != "given":
        return f"the log's stylus_r_mm {r.stylus_r_source}"
    if r.log_stylus_r_mm is None:
        return "--stylus-r-mm; the log says none"
    if r.log_stylus_r_mm == r.stylus_r_mm:
        return "--stylus-r-mm, as the log says"
    return f"--stylus-r-mm; the log says {r.log_stylus_r_mm:g} mm"


def _u95_basis(r) -> str:
    """``Student t, 6 dof; never below the rounding of X, Y, Z printed to 0.001 mm`` (the second part only for
    a log printed to a step: review31e F3)."""
    q = r.printing_step_mm
    if not any(v > 0 for v in q):
        return "Student t, %d dof" % r.dof
    names = ", ".join("XYZ"[:len(q)])
    steps = f"{q[0]:g}" if len(set(q)) == 1 else ", ".join(f"{v:g}" for v in q)
    return f"Student t, {r.dof} dof; never below the rounding of {names} printed to {steps} mm"


def _v(x, nd=6):
    return "(" + ", ".join(f"{c:.{nd}f}" for c in x) + ")"


def run(args) -> int:
    from core.atomic import json_safe, write_json_atomic
    from core.features import NORMAL_AGREE_MAX_DEG, fit_log_feature
    from scenarios.cli.reading import read_probe
    from scenarios.cli.guard import about_file, progress_line

    chosen = " ".join(f"--{k} {w}" for k, w in (("feature", args.feature), ("setup", args.setup)) if w)
    with progress_line("fit: % of the work") as bar:   # a 5,000-row log: 1-6 s on 2 busy cores
        def reading(done, lines):
            read_s = lines * READ_S_PER_LINE
            bar(int(100 * done / max(lines, 1) * read_s / (read_s + FIT_S)), 100)

        log = read_probe(args.log, "fit", progress=reading, bar=bar)
        with about_file(args.log, chosen):   # 'sphere fit: points are coplanar' names the log and the rows
            r = _fitted(log, args, fit_log_feature)
        bar(100, 100)
    v = r.values
    sel = "".join(f", {k} {w}" for k, w in (("feature", args.feature), ("setup", args.setup)) if w)
    print(f"{r.kind}: {r.n} touches{sel}, stylus radius {r.stylus_r_mm:g} mm applied ({_radius_from(r)})")
    if r.kind == "plane":
        print(f"  point {_v(v['point_mm'], 4)} mm, normal {_v(v['normal'])}")
    elif r.kind == "cylinder":
        print(f"  axis point {_v(v['point_mm'], 4)} mm, axis {_v(v['axis'])}, "
              f"radius {v['radius_mm']:.4f} mm ({v['side']})")
    else:
        print(f"  centre {_v(v['centre_mm'], 4)} mm, radius {v['radius_mm']:.4f} mm ({v['side']})")
    print("  U95 (" + _u95_basis(r) + "): " + ", ".join(
        f"{k} {u:.3g}" + (" (printing step)" if r.u95_rounding and u == r.u95_rounding[k] > r.u95_scatter[k] else "")
        for k, u in r.u95.items()))
    print(f"  {FORM[r.kind]} {r.form_um:.3f} um (peak-to-valley about the least-squares {r.kind}, "
          f"probing noise included), rms {r.rms_um:.3f} um")
    print(f"  the log's touch normals within {r.normal_angle_deg:.1f} deg of the fitted {r.kind}'s "
          f"(refused beyond {NORMAL_AGREE_MAX_DEG:g} deg)")
    if args.json:
        tg = log.col("target")[r.rows].astype(str).tolist()
        rep = {"format": FIT_FORMAT, "log": str(args.log), "kind": r.kind, "n": r.n, "feature": args.feature,
               "setup": args.setup,
               "values": v, "u95": r.u95, "u95_scatter": r.u95_scatter, "u95_rounding": r.u95_rounding,
               "printing_step_mm": list(r.printing_step_mm), "form": FORM[r.kind], "form_um": r.form_um,
               "rms_um": r.rms_um,
               "dof": r.dof, "stylus_r_mm": r.stylus_r_mm, "stylus_r_source": r.stylus_r_source,
               "log_stylus_r_mm": r.log_stylus_r_mm, "normal_angle_deg": r.normal_angle_deg,
               "touches": [{"row": int(i), "target": t, "residual_um": float(e)}
                           for i, t, e in zip(r.rows, tg, r.residuals_um)],
               "input_warnings": list(log.warnings)}
        write_json_atomic(args.json, json_safe(rep), special=True)
        print(f"wrote {args.json}")
    return 0
