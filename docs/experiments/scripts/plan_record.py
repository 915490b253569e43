"""Record every planning request of nav_eval (seed given), and which lattices (goals on the
same field) were cached before it, pickled (the field shared between requests)."""
import copy, dataclasses, pickle, sys
from bench import nav_eval
from autochair.nav import planner

seed = sys.argv[1] if len(sys.argv) > 1 else "7"
out = sys.argv[2]
reqs = []
real = nav_eval.compute
def rec(req, params=None):
    cached = {k[1] for k in planner._lattices if k[0] == id(req.field)}
    snap = dataclasses.replace(req, chain=copy.deepcopy(req.chain), people=copy.deepcopy(req.people))
    reqs.append((snap, params, cached))
    return real(req, params)
nav_eval.compute = rec
nav_eval.main(["--no-save", "--seed", seed] + sys.argv[3:])
with open(out, "wb") as f:
    pickle.dump(reqs, f, protocol=5)
print(len(reqs), "requests")
