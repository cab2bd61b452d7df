"""``vmt iso230-2 LOG --json OUT [--report DIR]``: evaluate a positioning test by ISO 230-2.

LOG is a positioning-log/1 file, an ecmc ``.dat`` (EPICS motion control)
or a table of target, cycle, direction, measured value. Every figure of
ISO 230-2 goes to the JSON in µm; ``--report`` adds a folder with the
standard's plot.

(``vmt simulate positioning`` lives in ``simulate.py``.)
"""

from __future__ import annotations

import sys


def register(sub) -> None:
    p = sub.add_parser("iso230-2", help="evaluate a positioning test (ISO 230-2): every figure, in µm",
                       description=__doc__.split("\n\n")[1])
    p.add_argument("log", help="positioning-log/1 CSV, ecmc .dat, or a table of target, cycle, direction, measured")
    p.add_argument("--json", required=True, metavar="OUT", help="JSON report to write (atomically)")
    p.add_argument("--report", help="folder for a readable report (index.html, the standard's plot)")
    from scenarios.cli.options import option

    # --from until session 33: one name with two meanings beside bench's --from-json FILE and machine program's
    # --from-row K (review32d F9); the old name works and says the new one
    option(p, "--log-kind", dest="kind", choices=("auto", "log", "ecmc", "table"), default="auto", old=("--from",),
           metavar=None, help="what LOG is (auto: '# format:' line -> log, TGT_DATA[ -> ecmc, else table)")
    p.add_argument("--write-log", metavar="LOG", help="also write the readings as positioning-log/1")
    p.add_argument("--comp-file", metavar="COMP",
                   help="also write a LinuxCNC compensation table (COMP_FILE_TYPE 0: nominal forward reverse, the "
                        "mean deviation per target and direction) at the axis (joint) positions: target + the "
                        "log's tool_offset_mm. LinuxCNC uses it INSTEAD of the joint's BACKLASH and of any earlier "
                        "COMP_FILE: test with both off, or give --add-to")
    p.add_argument("--add-to", metavar="OLD_COMP",
                   help="with --comp-file: the compensation file the joint had loaded during the test (its COMP_FILE); "
                        "the test measured what it left (a residual), and COMP is OLD_COMP plus that residual, "
                        "to load in its place (the residual alone would undo OLD_COMP)")
    p.add_argument("--comp-range-deg", metavar="LO:HI",
                   help="with --comp-file, a rotary axis (a log in degrees): the joint positions the table must cover, "
                        "deg (the joint's MIN_LIMIT:MAX_LIMIT; write --comp-range-deg=-400:800 when LO < 0): the "
                        "test's turn repeated every 360 deg out to them. Default: the two lines closing the turn "
                        "(last target - 360 .. first target + 360); beyond its lines LinuxCNC holds the end lines, "
                        "so a joint that turns further (a WRAPPED_ROTARY axis counts turns) needs this")
    g = p.add_argument_group("uncertainty of the test (ISO/TR 230-9 style; any of these adds U (k=2) per figure)")
    g.add_argument("--u-instrument-um", type=float, metavar="UM",
                   help="instrument, length-independent, standard uncertainty, µm")
    g.add_argument("--u-instrument-um-per-m", type=float, metavar="UM_PER_M",
                   help="instrument, per m of travel, standard uncertainty, µm/m")
    g.add_argument("--misalignment-urad", type=float, metavar="URAD",
                   help="largest beam-to-axis angle (cosine error), µrad")
    g.add_argument("--temp-c", type=float, metavar="C",
                   help="mean temperature of the machine scale during the test, °C (20), for the uncertainty only: the "
                        "readings must already be corrected to 20 °C (the laser's material-temperature "
                        "compensation); vmt corrects nothing and warns with L alpha (T - 20) when T is not 20")
    g.add_argument("--u-temp-k", type=float, metavar="K", help="standard uncertainty of that temperature, K")
    g.add_argument("--alpha-per-k", type=float, metavar="PER_K",
                   help="expansion coefficient of the correction applied to the readings, 1/K (11.5e-6)")
    g.add_argument("--u-alpha-per-k", type=float, metavar="PER_K", help="its standard uncertainty, 1/K")
    g.add_argument("--eve-um", type=float, metavar="UM",
                   help="environmental variation error E_VE (drift check range), µm")
    p.set_defaults(func=run)


_UNC = {"u_instrument_um": "u_instrument_um", "u_instrument_um_per_m": "u_instrument_um_per_m",
        "misalignment_urad": "misalignment_urad", "temp_c": "temperature_C", "u_temp_k": "u_temperature_K",
        "alpha_per_k": "alpha_per_K", "u_alpha_per_k": "u_alpha_per_K", "eve_um": "eve_um"}


def run(args) -> int:
    from core.positioning import UncertaintyInputs
    from scenarios.positioning import FIGURE_ROWS, evaluate_file

    from core.exceptions import ConfigError
    from core.positioning import PositioningLogError

    comp_range = _comp_range(args.comp_range_deg, args.comp_file) if args.comp_range_deg is not None else None
    given = {v: getattr(args, k) for k, v in _UNC.items() if getattr(args, k) is not None}
    try:
        unc = UncertaintyInputs(**given) if given else None
    except PositioningLogError as e:   # named by its option, not the field ('uncertainty input u_temperature_K')
        said = str(e)
        for dest, field in _UNC.items():
            said = said.replace(f"uncertainty input {field} ", f"--{dest.replace('_', '-')} ")
        raise ConfigError(said) from None
    from scenarios.cli.guard import progress_line

    # with --report: 2-3 s wall on 2 busy cores (the plot), without it 0.1 s (the line is not drawn then)
    with progress_line("iso230-2: % of the work") as bar:
        rep, warnings = evaluate_file(args.log, args.json, args.report, kind=args.kind, uncertainty=unc,
                                      write_log=args.write_log, comp_file=args.comp_file, add_to=args.add_to,
                                      comp_range_deg=comp_range,
                                      progress=bar if args.report else None)
    for w in warnings:
        print(f"vmt iso230-2: warning: {w}", file=sys.stderr)
    u = rep["unit"]
    sym = "um" if u == "um" else "arcsec"
    from core.positioning import cycles_said, skipped_said

    skipped = skipped_said(rep.get("readings") or {})
    print(f"{args.log}: axis {rep['axis'] or '?'}, {rep['targets']} targets x {cycles_said(rep)}"
          + (f", {rep['cycle_kind']} cycle" if rep.get("cycle_kind") else "") + (f"; {skipped}" if skipped else ""))
    if rep.get("cycle_note"):
        print(f"  note: {rep['cycle_note']}")
    st = rep.get("printed_step") or {}
    if st.get(f"u_reading_{sym}", 0.0) >= 0.0005:   # shown where it reaches the figures' printed digits
        unit = "mm" if sym == "um" else "deg"
        print(f"  readings printed to {st[f'step_{unit}']:g} {unit}: rounding u {st[f'u_reading_{sym}']:.3f} {sym} a "
              f"reading, R up to {st[f'u_R_{sym}']:.3f}, A {st[f'u_A_{sym}']:.3f}, B E M {st[f'u_E_{sym}']:.3f} "
              f"{sym} (1 sigma{', in U cond' if rep.get('uncertainty') else ''})")
    U = rep.get("uncertainty") or {}
    if U:
        print("  (U cond: the measuring conditions' expanded uncertainty, k = 2; sampling: 2 x std of the figure "
              "over repeats of this test, from its own readings)")
    for name, symbol, clause, meaning in FIGURE_ROWS:
        extra = (f"  (U cond {U[f'U_{name}_um']:.3f}, sampling {U[f'U_sampling_{name}_um']:.2f})"
                 if U and f"U_sampling_{name}_um" in U else f"  (U cond {U[f'U_{name}_um']:.3f})" if U else "")
        pad = " " * (4 - len(symbol.replace("\u0304", "")))  # B̄ carries a combining macron
        v = rep[f"{name}_{u}"]
        v = 0.0 if round(v, 3) == 0 else v   # a zero as 0.000, not -0.000 (float noise of mm subtraction, review34)
        print(f"  {symbol}{pad}{v:10.3f} {sym}{extra}   {meaning} [{clause}]")
    from pathlib import Path

    print(f"wrote {args.json}" + (f" and {Path(args.report) / 'index.html'}" if args.report else "")
          + (f" and {args.write_log}" if args.write_log else "") + (f" and {args.comp_file}" if args.comp_file else ""))
    if args.comp_file:
        print(f"note: {args.comp_file} " + (f"is {args.add_to} plus this test's residual: load it in {args.add_to}'s "
                                            "place" if args.add_to else COMP_FILE_NOTE))
    return 0


def _comp_range(text: str, comp_file) -> tuple:
    """``--comp-range-deg LO:HI`` as (lo, hi): two finite numbers, LO < HI, with --comp-file (else ConfigError)."""
    import math

    from core.exceptions import ConfigError

    if not comp_file:
        raise ConfigError("--comp-range-deg: give --comp-file too (the rotary table whose lines it extends)")
    try:
        v = [float(x) for x in text.split(":")]
    except ValueError:
        v = []
    if len(v) != 2 or not all(math.isfinite(x) for x in v) or not v[0] < v[1]:
        raise ConfigError(f"--comp-range-deg {text!r}: expected finite LO < HI in degrees, LO:HI "
                          "(write --comp-range-deg=-400:800 when LO < 0)")
    return v[0], v[1]


#: What `--comp-file` prints (review32a F2): how LinuxCNC takes the file, where it would undo a correction.
COMP_FILE_NOTE = ("replaces the joint's BACKLASH and any earlier COMP_FILE in LinuxCNC (one table per joint, "
                  "BACKLASH unused with it): it is right for a test made with both off; a test made with a table "
                  "loaded measured its residual: write --comp-file with --add-to OLD.comp. Like any per-joint table "
                  "it is exact on the line the test was measured along (the other axes where they stood), not "
                  "elsewhere where the axis's angular errors have an Abbe arm (README 'Compensation files')")
