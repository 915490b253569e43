import math, numpy as np, pickle, heapq, sys
import bench.nav_eval as ne
from autochair.runtime.config import ChairGeometry
ch = ChairGeometry(); fp = ne.Footprint(ch.front_m, ch.rear_m, ch.half_width_m)
import os; world, fld = ne.build(os.environ.get("WORLD","hallway"), fp)
G = pickle.load(open(os.environ.get("GRID","/tmp/fc/grid.pkl"), "rb"))
WMIN = float(sys.argv[1]) if len(sys.argv) > 1 else 0.10   # least |w| bound while turning
FEND = float(sys.argv[2]) if len(sys.argv) > 2 else 0.20   # least free fwd at a straight's end
CLR = 0.04
FINAL = os.environ.get('FINAL', '0') == '1'
# wall points
segs = world.segments; wp = []
for x1, y1, x2, y2 in segs:
    n = max(2, int(math.hypot(x2-x1, y2-y1) / 0.01)); t = np.linspace(0, 1, n)
    wp.append(np.c_[x1 + t*(x2-x1), y1 + t*(y2-y1)])
for cx, cy, r in world.circles:
    a = np.linspace(0, 2*math.pi, max(8, int(2*math.pi*r/0.01)))
    wp.append(np.c_[cx + r*np.cos(a), cy + r*np.sin(a)])
wp = np.vstack(wp)
def clearance(x, y, th):
    dx, dy = wp[:,0]-x, wp[:,1]-y; c, s = math.cos(th), math.sin(th)
    lx, ly = c*dx + s*dy, -s*dx + c*dy
    ex = np.maximum(np.maximum(lx - 0.95, -0.25 - lx), 0); ey = np.maximum(np.abs(ly) - 0.35, 0)
    inside = (lx <= 0.95) & (lx >= -0.25) & (np.abs(ly) <= 0.35)
    d = np.hypot(ex, ey); d[inside] = -1
    return float(d.min())
xs = sorted({k[0] for k in G}); ys = sorted({k[1] for k in G})
def snap(v, arr): return min(arr, key=lambda a: abs(a - v))
ok_pose = {}
def okp(k):
    if k not in ok_pose: ok_pose[k] = clearance(k[0], k[1], math.radians(k[2])) >= CLR
    return ok_pose[k]
def wb(k): return G[k][3]
def ff(k): return G[k][0]
def turn_ok(x, y, h0, h1):
    step = 10 if ((h1 - h0) % 360) <= 180 else -10
    h = h0
    while True:
        k = (x, y, h % 360)
        if k not in G or not okp(k) or wb(k) < WMIN: return False
        if h % 360 == h1 % 360: return True
        h += step
import os
start = tuple(float(v) if i < 2 else int(v) for i, v in enumerate(os.environ.get("START", "4.6,2.15,80").split(","))); goal = tuple(float(v) for v in os.environ.get("GOAL", "5.5,3.5").split(",")); GH = int(os.environ.get("GH", "180"))
# Dijkstra on (x, y, h); cost: path length + 0.3*turn rad
dist = {start: 0.0}; prev = {}; pq = [(0.0, start)]
best = None
while pq:
    d, s = heapq.heappop(pq)
    if d > dist.get(s, 1e9): continue
    x, y, h = s
    if (x, y) == goal and turn_ok(x, y, h, GH): best = s; break
    for h2 in range(0, 360, 10):
        if h2 != h and not turn_ok(x, y, h, h2): continue
        tc = 0.3 * math.radians(min((h2-h) % 360, (h-h2) % 360))
        for L in np.arange(0.05, 1.01, 0.05):
            qx, qy = x + L*math.cos(math.radians(h2)), y + L*math.sin(math.radians(h2))
            if not (xs[0] <= qx <= xs[-1] and ys[0] <= qy <= ys[-1]): break
            sx, sy = snap(qx, xs), snap(qy, ys)
            if math.hypot(sx-qx, sy-qy) > 0.03: continue
            k0 = (x, y, h2)
            if ff(k0) < L + (0.1 if FINAL else FEND) - 0.03: break
            k = (sx, sy, h2)
            if k not in G or not okp(k) or (ff(k) < FEND and not (FINAL and (sx, sy) == goal and turn_ok(sx, sy, h2, GH))): continue
            nd = d + tc + L + 0.2
            if nd < dist.get(k, 1e9):
                dist[k] = nd; prev[k] = s; heapq.heappush(pq, (nd, k))
if best is None: print("no way", WMIN, FEND, len(dist)); sys.exit()
path = [best]
while path[-1] in prev: path.append(prev[path[-1]])
for k in reversed(path): print(k, "ff=%.2f wb=%.2f clr=%.3f" % (ff(k), wb(k), clearance(k[0], k[1], math.radians(k[2]))))
