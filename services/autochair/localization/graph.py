"""2D pose graph, pure: nodes (x, y, yaw), relative-pose edges with 3×3 information, sparse
Gauss-Newton (scipy.sparse) with the first node held fixed. Small graphs (hundreds to a few
thousand keyframes) solve in milliseconds; see the notes for why not GTSAM."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse import linalg as splinalg

from .matching import F64, between


@dataclass(frozen=True)
class Edge:
    i: int
    j: int
    z: F64  # measured pose of j in i's frame
    info: F64  # (3, 3)
    loop: bool = False


def _wrap(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


class PoseGraph:
    def __init__(self) -> None:
        self.nodes: list[F64] = []
        self.edges: list[Edge] = []

    def add_node(self, pose: F64) -> int:
        self.nodes.append(np.array(pose, dtype=np.float64))
        return len(self.nodes) - 1

    def add_edge(self, i: int, j: int, z: F64, info: F64, loop: bool = False) -> None:
        self.edges.append(Edge(i, j, np.array(z, dtype=np.float64), info, loop))

    def error(self, e: Edge) -> F64:
        d = between(self.nodes[e.i], self.nodes[e.j])
        cz, sz = math.cos(e.z[2]), math.sin(e.z[2])
        dx, dy = d[0] - e.z[0], d[1] - e.z[1]
        return np.array([cz * dx + sz * dy, -sz * dx + cz * dy, _wrap(d[2] - e.z[2])])

    def chi2(self) -> float:
        return float(sum(self.error(e) @ e.info @ self.error(e) for e in self.edges))

    def optimize(self, iterations: int = 10) -> float:
        """Gauss-Newton; returns the final χ²."""
        n = len(self.nodes)
        if n < 2 or not self.edges:
            return 0.0
        for _ in range(iterations):
            rows: list[int] = []
            cols: list[int] = []
            vals: list[float] = []
            b = np.zeros(3 * n)
            for e in self.edges:
                xi, xj = self.nodes[e.i], self.nodes[e.j]
                ci, si = math.cos(xi[2]), math.sin(xi[2])
                cz, sz = math.cos(e.z[2]), math.sin(e.z[2])
                rz_t = np.array([[cz, sz], [-sz, cz]])
                ri_t = np.array([[ci, si], [-si, ci]])
                dt = xj[:2] - xi[:2]
                a = np.zeros((3, 3))
                bj = np.zeros((3, 3))
                a[:2, :2] = -rz_t @ ri_t
                a[:2, 2] = rz_t @ np.array([-si * dt[0] + ci * dt[1], -ci * dt[0] - si * dt[1]])
                a[2, 2] = -1.0
                bj[:2, :2] = rz_t @ ri_t
                bj[2, 2] = 1.0
                err = self.error(e)
                for (p, jp), (q, jq) in (((e.i, a), (e.i, a)), ((e.i, a), (e.j, bj)),
                                         ((e.j, bj), (e.i, a)), ((e.j, bj), (e.j, bj))):
                    blk = jp.T @ e.info @ jq
                    r, c = np.meshgrid(np.arange(3) + 3 * p, np.arange(3) + 3 * q, indexing="ij")
                    rows += r.ravel().tolist()
                    cols += c.ravel().tolist()
                    vals += blk.ravel().tolist()
                b[3 * e.i:3 * e.i + 3] += a.T @ e.info @ err
                b[3 * e.j:3 * e.j + 3] += bj.T @ e.info @ err
            rows += [0, 1, 2]  # hold the first node: the map frame is where mapping started
            cols += [0, 1, 2]
            vals += [1e9, 1e9, 1e9]
            h = sparse.csc_matrix((vals, (rows, cols)), shape=(3 * n, 3 * n))
            dx = splinalg.spsolve(h, -b)
            for k in range(n):
                self.nodes[k] = self.nodes[k] + dx[3 * k:3 * k + 3]
                self.nodes[k][2] = _wrap(self.nodes[k][2])
            if float(np.abs(dx).max()) < 1e-5:
                break
        return self.chi2()
