"""``vmt vcmm --plan PLAN --machine NAME|FILE --task TASK.toml --json OUT``: the uncertainty of your own measurement.

A virtual CMM (ISO 15530-4): the plan (probe-log/1, nominal points and
normals) is probed on the machine again and again, each run with the
machine's declared error limits drawn anew (the task's [declared] tables)
and the probe's noise; the task's features are fitted and its measurands
evaluated. Monte Carlo per JCGM 101 (adaptive: batches until y, u and the
95 % interval of every measurand are stable), then the budget, one
source at a time. The interval holds what the model holds: an error in
neither the machine file, the task nor --machine-state is taken as zero.
Features are fitted in the machine frame: a measurand over features probed
at different rotary positions is refused. The task file is described in
the README ("Virtual CMM").
"""

from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("vcmm", help="Monte Carlo uncertainty of a user's measurands on a machine (virtual CMM)",
                       description=__doc__.split("\n\n")[1])
    from scenarios.cli.options import add_machine_args, add_noise_arg, add_plan_arg

    add_plan_arg(p, "probe-log/1 plan (or log: its nominal columns are used)")

    add_machine_args(p, default=None, required=True,
                     what="the machine, its errors your best estimate (required, unlike simulate's and scenario's "
                          "--machine: those run a study on the artefact's or plan's own machine, this is the "
                          "uncertainty of your measurement on your machine, and no default stands in for it)",
                     errors_default="none", errors_why="best-estimate errors: a built-in machine's as its file "
                                                       "states them, none; name a set to take it as your estimate")
    p.add_argument("--task", required=True, metavar="TASK.toml", help="features, measurands, declared limits")
    p.add_argument("--json", required=True, metavar="OUT", help="result to write (JSON, atomically)")
    p.add_argument("--report", help="folder for a readable report (index.html, the budget chart)")
    p.add_argument("--seed", type=int, default=0, help="seed of the draws (0); same seed, same result")
    add_noise_arg(p, "default: the task's [probe], else the machine's")
    p.add_argument("--tol-um", type=float, default=None,
                   help="JCGM 101 numerical tolerance on y, u and the interval ends, um "
                        "(default: the task's [mc], else 2 significant digits of u)")
    p.add_argument("--machine-state", default=None, metavar="RESULT.json",
                   help="an identification result (vmt identify --json, vmt scenario mfb-3axis --json): its "
                        "estimate replaces the machine file's errors it covers, each run draws the state from "
                        "its covariance; the task's [declared] limits add what it does not cover")
    p.add_argument("--sobol-runs", type=int, default=0, metavar="N",
                   help="also first-order Sobol indices of every source, N runs per matrix (N (k + 2) runs for "
                        "k sources; 0: none; each run measures the plan once with every source drawn; the "
                        "uncertainty's own runs stop by --tol-um, not by a count)")
    p.add_argument("--no-budget", action="store_true", help="skip the one-at-a-time budget runs")
    p.add_argument("--dask", default=None, metavar="tcp://HOST:PORT",
                   help="run the Monte Carlo batches on this Dask cluster (the same result for a seed)")
    p.set_defaults(func=run)


def _fmt(v, unit):
    return f"{v:.6f} {unit}" if unit in ("mm", "deg") else f"{v:.4f} {unit}"


def _u_decimals(tol) -> int:
    """Decimals to print u and U to: the place the run's numerical tolerance makes reliable (JCGM 101 7.9.2:
    delta = 1/2 10^l, u stable to the digit of 10^l; review32b F1.2: 4 decimals where significant_digits = 1
    made one reliable); 4 when no tolerance is given. The JSON keeps every digit."""
    import math

    if tol is None or not (tol > 0) or not math.isfinite(tol):
        return 4
    return max(0, min(6, -math.floor(math.log10(2 * tol) + 1e-9)))


def _tool_offset(plan, spec, path) -> dict:
    """The J the runs probe with, the machine's ``[tool] offset_mm``, as its JSON record (``tool_offset``: from
    ``machine``, or ``machine and log`` when the plan's ``tool_offset_mm`` line says the same J, or ``assumed``
    with its ``note`` where the machine file gives no ``[tool]`` and the plan no line:
    :func:`sim.machinefile.tool_offset_note`). A plan that is a log of touches made with another J (its
    ``tool_offset_mm`` line, vmt probe / import grbl --tool-offset-mm) is refused: the runs would be another tool's
    touches (its Abbe arms through the machine's angular errors), and the log is the record of the tool used."""
    from core.exceptions import ConfigError
    from hardware.campaign import tool_offset_text
    from scenarios.cli.options import log_tool_offset, same_tool_offset, tool_offset_record
    from sim.machinefile import tool_offset_note

    cfg = spec.config
    note = tool_offset_note(spec)
    J_cfg = [round(float(v) * 1e3, 9) for v in cfg.J_m]   # mm, as the files round J (1e-9 mm)
    J_log = log_tool_offset(plan)
    if J_log is None:
        return tool_offset_record(J_cfg, "machine") if note is None else tool_offset_record(J_cfg, "assumed", note)
    if not same_tool_offset(J_log, J_cfg):
        raise ConfigError(f"{path}: its tool_offset_mm line says its touches were logged with J = "
                          f"{tool_offset_text(J_log)} mm, the machine {cfg.name}'s [tool] offset_mm is "
                          f"{tool_offset_text(J_cfg)} mm{' (' + note + ')' if note else ''}: the runs would be "
                          "another tool's touches; give a machine file whose [tool] offset_mm is the log's J")
    return tool_offset_record(J_log, "machine and log")


def run(args) -> int:
    import dataclasses

    from core.atomic import json_safe, write_json_atomic
    from core.exceptions import ConfigError
    from scenarios.cli.reading import read_probe
    from core.vcmm import load_task
    from scenarios.cli.guard import progress_line, said
    from scenarios.cli.options import tool_offset_said
    from scenarios.vcmm import prepare, study
    from sim.machinefile import truth_machine

    task = load_task(args.task)
    if args.tol_um is not None:
        if not (args.tol_um > 0 and args.tol_um < float("inf")):
            raise ConfigError(f"--tol-um must be a positive number, got {args.tol_um:g}")
        task = dataclasses.replace(task, mc=dataclasses.replace(task.mc, tolerance=args.tol_um * 1e-6))
    if args.sobol_runs < 0 or args.sobol_runs == 1:
        raise ConfigError(f"--sobol-runs must be 0 or >= 2, got {args.sobol_runs}")
    spec = truth_machine(args.machine, args.errors, "none")
    plan = read_probe(args.plan, "vcmm")
    J_said = _tool_offset(plan, spec, args.plan)   # a log of another tool refused before any run
    state = lobing = None
    if args.machine_state is not None:
        from core.state import read_estimate

        state = read_estimate(args.machine_state)
        from core.state import identified_on_mismatch

        cfg = spec.config
        why = identified_on_mismatch(state, cfg.name, cfg.chain)
        if why:
            raise ConfigError(f"--machine-state {args.machine_state}: {why}")
        if state.identified_on is None:
            print(f"{args.machine_state}: no record of the machine it was identified on (a file written before "
                  f"session 26): applied to {cfg.name} unchecked")
        from core.state import probe_offsets_check

        why, notice = probe_offsets_check(state, [v * 1e3 for v in cfg.J_m])
        if why:
            raise ConfigError(f"--machine-state {args.machine_state}: {why}")
        if notice:
            print(notice)
        # when and at what temperature it was identified (review33a F8), beside the plan's own sensors
        from core.state import describe_conditions, log_conditions, temperature_notice

        for line in (describe_conditions(state), temperature_notice(state, log_conditions(plan)["temperature_C"])):
            if line:
                print(line)
        state = state.at_axis_positions(cfg.J_m)   # a state at the readings (J unknown): at reading + this J
    st = prepare(plan, task, spec, noise_um=args.noise_um, state=state)
    if state is not None:   # what the state cannot carry: its scale (session 37), its gauge and a probe lobing
        import json   # its identification found (session 38; the lobing's record is beside the estimate)
        from pathlib import Path

        from scenarios.vcmm import identification_lobing, state_carry_check   # refused when it moves a measurand

        lobing = identification_lobing(json.loads(Path(args.machine_state).read_text()))
        why, notice = state_carry_check(st, lobing)
        if why:
            raise ConfigError(why)
        if notice:
            print(notice)
    # adaptive (JCGM 101 7.9): the total is the runs foreseen now, revised as the batches come in (review32d F10)
    with progress_line("vcmm: Monte Carlo runs (adaptive: total as foreseen now)") as bar:
        rep = study(st, args.seed, progress=bar, budget=not args.no_budget, dask=args.dask,
                    sobol_runs=args.sobol_runs)
        bar.clear()
    rep.pop("values_si")
    if state is not None and lobing is not None:   # run below the refusal's ratio: the JSON says it is left out
        from scenarios.vcmm import lobing_entry

        rep["machine_state"]["cannot_carry"].append(lobing_entry(st, lobing))
    rep["plan"] = str(args.plan)
    rep["input_warnings"] = list(plan.warnings)
    rep["tool_offset"] = J_said
    print(f"{args.plan}: {rep['touches']} touches on {rep['machine']}, {rep['runs']} runs "
          f"({rep['runs_total']} with the budget, {rep['runs_per_s']:.1f} runs/s), seed {args.seed}")
    print(tool_offset_said(J_said["J_mm"], J_said["from"], "the runs", J_said.get("note")))   # identify's words
    for m in rep["measurands"]:
        tail = "" if m["converged"] else "  NOT CONVERGED (max_runs reached)"
        d = _u_decimals(m.get("tolerance"))
        print(f"  {m['name']}: nominal {_fmt(m['nominal'], m['unit'])}, bias {m['bias']:+.4f} {m['u_unit']}, "
              f"u {m['u']:.{d}f} {m['u_unit']}, U{100 * m['coverage']:g} {m['U']:.{d}f} {m['u_unit']}, "
              f"{100 * m['coverage']:g} % interval [{_fmt(m['interval'][0], m['unit'])}, "
              f"{_fmt(m['interval'][1], m['unit'])}]{tail}")
        lo, hi = m["error_interval"]   # the true value is measured - error (review33a F6)
        minus = lambda e: f"measured {'-' if e >= 0 else '+'} {abs(e):.{d}f}"   # noqa: E731
        print(f"      the true value ({100 * m['coverage']:g} %): in [{minus(hi)}, {minus(lo)}] {m['u_unit']}, "
              f"or measured +- {m['U_about_true']:.{d}f} {m['u_unit']}"
              + (f"; BIASED by {m['error_mean']:+.{d}f} {m['u_unit']}: measured +- U{100 * m['coverage']:g} "
                 f"covers it in {100 * m['U_covers_true']:.0f} % of runs" if m["biased"] else ""))
        for b in sorted(m["budget"], key=lambda b: -b["u"]):
            print(f"      {b['source']:24s} u {b['u']:.{d}f} {m['u_unit']}  ({100 * b['share']:.1f} %)")
        if m["sobol_first_order"]:
            se = m["sobol_first_order_se"]
            print("      first-order Sobol (+- standard error): " + ", ".join(
                f"{k} {v:.3f} +- {se[k]:.3f}" for k, v in m["sobol_first_order"].items() if v is not None))
    if args.report:
        from scenarios.vcmm import write_report

        write_report(args.report, rep)
    write_json_atomic(args.json, json_safe(rep), special=True)
    from pathlib import Path

    print(f"wrote {said(args.json)}" + (f" and {Path(args.report) / 'index.html'}" if args.report else ""))
    return 0
