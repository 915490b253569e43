# Session 18 (helper A): import math, random, sys, time
sys.path.insert(0, "/tmp/s18A")
from autochair.control.limits import move_all
from autochair.control.limits import SCurveAxis
rnd = random.Random(int(sys.argv[1]) if len(sys.argv) > 1 else 1)
worst = 0.0; nbad = 0; ncmp = 0; t_old = t_new = 0.0
for trial in range(int(sys.argv[2]) if len(sys.argv) > 2 else 3000):
    K = rnd.randint(1, 30); dt = 0.05; n = rnd.choice([12, 30])
    w0 = rnd.uniform(-1.0, 1.0) if rnd.random() < 0.8 else rnd.choice([0.0, 0.9, -0.9])
    q0 = rnd.uniform(-3, 3) if rnd.random() < 0.8 else 0.0
    es = [rnd.uniform(-math.pi, math.pi) * (rnd.random() ** 2) for _ in range(K)]
    A = [SCurveAxis(0.9, 2.8, 7.7) for _ in range(K)]; B = [SCurveAxis(0.9, 2.8, 7.7) for _ in range(K)]
    for a in A + B: a.reset(w0, q0)
    ya = [0.0] * K; yb = [0.0] * K
    for k in range(n):
        t0 = time.perf_counter()
        wa = [a.move(e - y, dt) for a, e, y in zip(A, es, ya)]
        t1 = time.perf_counter()
        wb = move_all(B, [e - y for e, y in zip(es, yb)], dt)
        t2 = time.perf_counter()
        t_old += t1 - t0; t_new += t2 - t1
        for i in range(K):
            ya[i] += wa[i] * dt; yb[i] += wb[i] * dt
            ncmp += 1
            same = (A[i].value, A[i].rate, A[i]._plan_state, A[i]._left) == (B[i].value, B[i].rate, B[i]._plan_state, B[i]._left)
            if not same:
                nbad += 1
                worst = max(worst, abs(ya[i] - yb[i]), abs(A[i].rate - B[i].rate) * dt * dt)
print("steps compared", ncmp, "not bit-identical", nbad, "worst", worst, "time old %.2f new %.2f s" % (t_old, t_new))
