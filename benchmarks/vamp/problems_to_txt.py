"""A manyhands problems.json (the MotionBenchMaker sets' format) as the line format driver.cc
reads: per valid problem `P set index`, `S start`, `G goal` (one per goal), `sphere x y z r`,
`box x y z qx qy qz qw hx hy hz`, `cyl x y z qx qy qz qw radius length`, `E`.
usage: python3 problems_to_txt.py problems.json [set,set,...] > problems.txt"""
import json
import sys

d = json.load(open(sys.argv[1]))
sets = sys.argv[2].split(",") if len(sys.argv) > 2 else None
out = []
for name, probs in d["problems"].items():
    if sets and name not in sets:
        continue
    for p in probs:
        if not p.get("valid", True):
            continue
        out.append("P %s %d" % (name, p["index"]))
        out.append("S " + " ".join(map(repr, p["start"])))
        for g in p["goals"]:
            out.append("G " + " ".join(map(repr, g)))
        for s in p.get("sphere", []):
            out.append("sphere %r %r %r %r" % (*s["position"], s["radius"]))
        for b in p.get("box", []):
            out.append("box " + " ".join(map(repr, b["position"] + b["orientation_quat_xyzw"] + b["half_extents"])))
        for c in p.get("cylinder", []):
            out.append("cyl " + " ".join(map(repr, c["position"] + c["orientation_quat_xyzw"] + [c["radius"], c["length"]])))
        out.append("E")
print("\n".join(out))
