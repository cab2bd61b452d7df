"""Truth of stylus_bending's pretravel_change_um (engine convention, up to a sign s found empirically) per campaign."""
import json, sys, importlib, time
import numpy as np
from core.touches import from_log
gen = sys.argv[1]
mod = importlib.import_module(f"scenarios.blind.{gen}")
seeds = sorted({json.loads(l)["seed"] for l in open(f"/tmp/u95/{gen}.jsonl") if json.loads(l)["effect"] == "stylus_bending"})
out = {}
for s in seeds:
    log, tr = mod.generate("stylus_bending", s)
    t = from_log(log)
    e = np.arcsin(np.clip(-t.d_R[:, 2], -1, 1))
    e = e[np.isfinite(e)]
    lo, hi = float(e.min()), float(e.max())
    if gen == "gen_a":
        a, c1, c2 = tr.physical["amplitude_um"], tr.params["c1"], tr.params["c2"]
        d = lambda ee: a * (c1 * np.sin(-ee) + c2 * (1 - np.cos(-ee)))   # the generator's elevation is -e
    else:
        ph, k = tr.params["bend_horizontal_um"], tr.params["friction_unload"]
        d = lambda ee: ph / (1 + k * np.sin(ee)) - ph   # gen_b's lay.elev_deg: assumed the engine's sign
    out[s] = [float(d(hi) - d(lo)), lo, hi]
json.dump(out, open(f"/tmp/u95/bend_{gen}.json", "w"))
print(len(out))
