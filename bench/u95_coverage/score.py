"""Coverage of named causes' magnitudes against the generators' truths: before (beside the named causes) and
after (session 20's rule, computed from the harness's 'none' and 'free' records with core.discover._beside_smooth,
or read from the report when the harness ran the new code)."""
import json, sys, collections
import numpy as np
sys.path.insert(0, ".")
from core.discover import _beside_smooth, Settings

ALPHA = Settings().alpha_family

def truths(r, f):
    """{key: (truth in the engine's convention, kind)} for the finding f of cause == effect; kind 'zero' marks a
    non-negative magnitude (hypot) whose truth is 0 (scored apart)."""
    g, e, tr = r["gen"], r["effect"], r["truth"]
    p, ph = tr.get("params") or {}, tr.get("physical") or {}
    out = {}
    if g == "gen_a":
        if e == "reversal":
            ax = p["axis"].lower()
            out[f"{ax}_lost_motion_um"] = (-ph["lost_motion_um"], "value")
            out[f"{'y' if ax == 'x' else 'x'}_lost_motion_um"] = (0.0, "value")
        elif e == "periodic_axis_error":
            ax = p["axis"]
            if f["params"].get("axis") == ax:
                out[f"E{ax}{ax}_amplitude_um"] = (ph["amplitude_um"], "value")
                out[f"E{'Y' if ax == 'X' else 'X'}{ax}_amplitude_um"] = (0.0, "zero")
                out["period_mm"] = (p["period_mm"], "value")
        elif e == "probe_lobing":
            k = int(p["lobes"])
            for j in range(1, 5):
                out[f"k{j}_amplitude_um"] = (ph["amplitude_um"], "value") if j == k else (0.0, "zero")
            out["pretravel_variation_pv_um"] = (2 * ph["amplitude_um"], "value")
        elif e == "temperature_expansion":
            out["alpha_x_um_per_m_K"] = (ph["alpha_x_um_per_m_per_K"], "value")
            out["alpha_y_um_per_m_K"] = (ph["alpha_y_um_per_m_per_K"], "value")
        elif e == "lobing_per_setup":
            if f["params"].get("harmonic") == p["lobes"]:
                out["amplitude_um"] = (ph["amplitude_um"], "value")
        elif e == "local_scale_defect":
            if f["params"].get("axis") == p["axis"]:
                out["amplitude_um"] = (ph["amplitude_um"], "value")
                out["centre_mm"] = (p["centre_mm"], "value")
                out["half_width_mm"] = (p["half_width_mm"], "value")
        elif e == "stylus_bending" and BEND.get(g) and str(r["seed"]) in BEND[g]:
            out["pretravel_change_um"] = (SIGN.get(g + "_bend", 1) * BEND[g][str(r["seed"])][0], "value")
    elif g == "gen_b":
        if e == "reversal":
            out["x_lost_motion_um"] = (-p["lost_motion_x_um"], "value")
            out["y_lost_motion_um"] = (-p["lost_motion_y_um"], "value")
        elif e == "periodic_axis_error":
            ax = "Y" if p["axis_is_y"] else "X"
            per = f["params"].get("period_mm")
            if f["params"].get("axis") == ax and per is not None:
                if abs(per - p["pitch_mm"]) < 0.05 * p["pitch_mm"]:
                    out[f"E{ax}{ax}_amplitude_um"] = (p["a1_um"], "value")
                    out["period_mm"] = (p["pitch_mm"], "value")
                elif abs(per - p["pitch_mm"] / 2) < 0.05 * p["pitch_mm"]:
                    out[f"E{ax}{ax}_amplitude_um"] = (p["a2_um"], "value")
                    out["period_mm"] = (p["pitch_mm"] / 2, "value")
                out[f"E{'Y' if ax == 'X' else 'X'}{ax}_amplitude_um"] = (0.0, "zero")
        elif e == "probe_lobing":
            out["k3_amplitude_um"] = (p["lobe3_um"], "value")
            for j in (1, 2, 4):
                out[f"k{j}_amplitude_um"] = (0.0, "zero")
        elif e == "temperature_expansion":
            out["alpha_x_um_per_m_K"] = (p["alpha_x_um_per_m_K"], "value")
            out["alpha_y_um_per_m_K"] = (p["alpha_y_um_per_m_K"], "value")
        elif e == "lobing_per_setup":
            if f["params"].get("harmonic", 3) == 3:
                out["amplitude_um"] = (p["lobe3_um"], "value")
        elif e == "stylus_bending" and BEND.get(g) and str(r["seed"]) in BEND[g]:
            out["pretravel_change_um"] = (SIGN.get(g + "_bend", 1) * BEND[g][str(r["seed"])][0], "value")
    elif g == "sim":
        if e == "reversal":
            ax = "x" if p["symbol"] == "EXX" else "y"
            out[f"{ax}_lost_motion_um"] = (SIGN.get("sim_rev", 1) * p["lost_motion_um"], "value")
            out[f"{'y' if ax == 'x' else 'x'}_lost_motion_um"] = (0.0, "value")
        elif e == "periodic_axis_error":
            sym = p["symbol"]  # E<err><axis>
            if f["params"].get("axis") == sym[2]:
                out[f"{sym}_amplitude_um"] = (p["amplitude_um"], "value")
                out[f"E{'Y' if sym[1] == 'X' else 'X'}{sym[2]}_amplitude_um"] = (0.0, "zero")
                out["period_mm"] = (p["period_mm"], "value")
        elif e == "probe_lobing":
            out["k3_amplitude_um"] = (p["k3_amplitude_um"], "value")
            out["k2_amplitude_um"] = (p["k2_amplitude_um"], "value")
            out["k1_amplitude_um"] = (0.0, "zero")
            out["k4_amplitude_um"] = (0.0, "zero")
        elif e == "temperature_expansion":
            ax = "x" if p["symbol"] == "EXX" else "y"
            out[f"alpha_{ax}_um_per_m_K"] = (SIGN.get("sim_te", 1) * p["alpha_um_per_m_K"], "value")
            out[f"alpha_{'y' if ax == 'x' else 'x'}_um_per_m_K"] = (0.0, "value")
        elif e == "lobing_per_setup":
            if f["params"].get("harmonic", 2) == 2:
                out["amplitude_um"] = (p["k2_amplitude_um"], "value")
    return out

SIGN = {"gen_a_bend": int(__import__("os").environ.get("BEND_A", "1")), "gen_b_bend": int(__import__("os").environ.get("BEND_B", "1"))}
import os
BEND = {g: json.load(open(f"/tmp/u95/bend_{g}.json")) for g in ("gen_a", "gen_b") if os.path.exists(f"/tmp/u95/bend_{g}.json")}

def modes_of(r, f_idx, f):
    """(before, after) (params, u95) of finding f."""
    if r.get("modes") and "none" in r["modes"]:
        b = r["modes"]["none"][f_idx]
        if "ridge" in r["modes"]:  # the first harness: session 20's rule is the penalised fit's, with the carry
            fr = r["modes"]["ridge"][f_idx]
            v, u, _ = _beside_smooth(b["params"], b["u95"], fr["params"], fr["u95"], ALPHA)
            return (b["params"], b["u95"]), (v, u)
        new = r["modes"]["new"][f_idx]
        return (b["params"], b["u95"]), (new["params"], new["u95"])
    return (f["params"], f["u95"]), (f["params"], f["u95"])

SMOOTH = {}

def main(paths):
    cnt = collections.defaultdict(lambda: [0, 0, 0, 0, 0, 0])  # n, in_before, in_after, n_after(reported), smooth, n_before
    rows = []
    fix = {}
    if os.path.exists("/tmp/u95/sim_fix.jsonl"):  # sim campaigns re-run on the final code (the first sim run had the free fit)
        for l in open("/tmp/u95/sim_fix.jsonl"):
            x = json.loads(l); fix[(x["gen"], x["effect"], x["seed"])] = x
    for path in paths:
        for l in open(path):
            r = json.loads(l)
            r = fix.get((r["gen"], r["effect"], r["seed"]), r)
            for i, f in enumerate(r["findings"]):
                if f["cause"] != r["effect"]:
                    continue
                tr = truths(r, f)
                if not tr:
                    continue
                (pb, ub), (pa, ua) = modes_of(r, i, f)
                for key, (t, kind) in tr.items():
                    vb, uB, va, uA = pb.get(key), ub.get(key), pa.get(key), ua.get(key)
                    if vb is None and va is None:
                        continue
                    c = cnt[(r["gen"], r["effect"], kind) + ((key,) if os.environ.get("PERKEY") else ())]
                    c[0] += 1
                    okb = vb is not None and uB is not None and abs(vb - t) <= uB
                    oka = va is not None and uA is not None and abs(va - t) <= uA
                    c[1] += okb
                    c[2] += oka
                    c[3] += va is not None and uA is not None
                    c[5] += vb is not None and uB is not None
                    c[4] += bool(r.get("smooth"))
                    if r.get("smooth"):
                        sm = SMOOTH.setdefault(kind, [0, 0, 0, 0, 0])
                        sm[0] += 1; sm[1] += vb is not None and uB is not None; sm[2] += okb
                        sm[3] += va is not None and uA is not None; sm[4] += oka
                    if r.get("smooth") or (okb != oka):
                        rows.append((r["gen"], r["effect"], r["seed"], key, t, vb, uB, va, uA, r.get("smooth"), f["confidence"]))
    print(f"{'set':40s} {'n':>5s} {'before':>12s} {'after':>12s}  beside-smooth")
    tot = [0, 0, 0]
    for k in sorted(cnt):
        n, ib, ia, ra, sm, rb = cnt[k]
        print(f"{'/'.join(k):40s} {n:5d} {ib:5d} ({ib / n:5.1%}) {ia:5d} ({ia / n:5.1%})  {sm}  reported b/a {rb}/{ra}")
        if k[2] == "value":  # (with PERKEY the same sums)
            tot[0] += n; tot[1] += ib; tot[2] += ia
    if tot[0]:
        print(f"{'all (truth-zero hypot apart)':40s} {tot[0]:5d} {tot[1]:5d} ({tot[1]/tot[0]:5.1%}) {tot[2]:5d} ({tot[2]/tot[0]:5.1%})")
    for kind, (n, rb, ib, ra, ia) in SMOOTH.items():
        print(f"beside a smooth, {kind}: {n} magnitudes; before {rb} reported, {ib} truth inside U95; after {ra} reported, {ia} inside")
    print("campaigns beside a smooth, or whose coverage moved:")
    for x in rows:
        print("  ", x[:4], f"truth {x[4]:.3g} before {x[5]} +- {x[6]} after {x[7]} +- {x[8]}", x[9], x[10])

if __name__ == "__main__":
    main(sys.argv[1:])

def decisions(paths):
    n = sm = moved = 0
    eff = collections.Counter()
    for path in paths:
        for l in open(path):
            r = json.loads(l)
            n += 1
            if not r.get("modes"):
                continue
            sm += 1
            ms = list(r["modes"].values())
            dec = [[(f["cause"], f["confidence"]) for f in m] for m in ms]
            named_beside = [f["cause"] for f in ms[0] if f["cause"] not in ("unexplained", "outlier")]
            if named_beside:
                eff[(r["gen"], r["effect"], r["seed"], tuple(named_beside), r["smooth"])] += 1
            if any(d != dec[0] for d in dec):
                moved += 1
                print("MOVED", r["gen"], r["effect"], r["seed"], dec)
    print(f"{n} campaigns, {sm} with an unnamed smooth adopted, decisions moved in {moved}; a named cause beside it in {len(eff)}:")
    for k in sorted(eff):
        print("   ", k)
