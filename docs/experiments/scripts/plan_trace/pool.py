"""Pools traced live_plan runs (ab.sh): python pool.py OUT TAG...; driving / blocked cycle
wall times, overlap with a field build, CPU, run-queue wait, the rest (GIL and lock waits)."""
import json, glob, statistics as st, numpy as np, sys
def q(xs): return "n=%3d med=%6.1f p95=%6.1f" % (len(xs), st.median(xs), np.percentile(xs, 95)) if xs else "n=0"
for v in ("old", "new"):
    D = []; B = []; OV = []; NO = []; HQ = []; RQ = []; RS = []
    for tag in sys.argv[2:]:
        for f in sorted(glob.glob(f"{sys.argv[1]}/{tag}-{v}-*.jsonl")):
            recs = [json.loads(l) for l in open(f)]
            F = [r for r in recs if r["kind"] == "field"]
            fs = [(x.get("s_NavField", x["t0"]), x["t0"] + x["wall"] / 1e3) for x in F]
            if not all("s_NavField" in x for x in F): continue
            for r in recs:
                if r["kind"] != "plan": continue
                a, b = r["t0"], r["t0"] + r["wall"] / 1e3
                ov = sum(max(0, min(b, y) - max(a, x)) for x, y in fs) * 1e3
                r["rest"] = r["wall"] - r["cpu"] - r["runq"] - (r.get("h_wall", 0) - r.get("h_cpu", 0) - r.get("h_runq", 0))
                (B if r["blocked"] else D).append(r)
                if not r["blocked"]: (OV if ov > 0.3 * r["wall"] else NO).append(r["wall"])
    print(v, "driving", q([r["wall"] for r in D]), "| blocked", q([r["wall"] for r in B]))
    print("   driving overlapped>30%:", q(OV), " not:", q(NO), " frac %.2f" % (len(OV) / len(D)))
    for k in ("cpu", "runq", "rest"):
        print("   driving %-5s" % k, q([r[k] for r in D]), "| blocked", q([r[k] for r in B]))
    print("   helper queue (h_wall-h_child) blocked", q([r.get("h_wall", 0) - r.get("h_child_wall", 0) for r in B]))
