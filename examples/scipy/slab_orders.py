"""The order of the slabs in slab Gauss-Seidel, on a written system: PCG iterations.

meshflow sweeps the slabs in odd-even order (all even slabs, then all odd ones, each half in
parallel) and runs CG on the odd slabs alone (src/flow/solve/reduced.rs: 19 slab solves an
iteration at 20 frames). A sweep in natural order (slab 0, 1, 2, ...; SciPy pipeline's `gs`),
or from both ends at once (0 and S-1, then 1 and S-2, ...: two slabs at a time), couples every
slab to the one solved just before it, and block SSOR over-relaxes by w:

    z = (D + w U)^-1 D (D + w L)^-1 r     (L, U: the links to slabs earlier, later in the order)

with 2S - 1 slab solves an application. w = 1 in odd-even order is meshflow's preconditioner.

    cargo run --release --example space_time_system -- 128 95 20 1 1 /tmp/system
    python3 examples/scipy/slab_orders.py /tmp/system [1,1.3,1.6]

(docs/scaling.md, "The slabs' order in the sweep").
"""

import sys

import numpy as np

from time_multigrid import Level, load, pcg_iterations


def orders(slabs):
    ends = [s for i in range((slabs + 1) // 2) for s in sorted({i, slabs - 1 - i})]
    return {
        "odd-even": list(range(0, slabs, 2)) + list(range(1, slabs, 2)),
        "natural": list(range(slabs)),
        "both ends": ends,
    }


def ssor(level, order, w):
    """Block SSOR(w) over the slabs of `level` in `order`."""
    rank = {s: i for i, s in enumerate(order)}

    def links(v, s, before):
        """Σ over the neighbours t of s solved before (after) s of A_st v_t."""
        out = np.zeros(level.n)
        if s > 0 and (rank[s - 1] < rank[s]) == before:
            out += level.x[s - 1] @ level.slab(v, s - 1)
        if s + 1 < level.slabs and (rank[s + 1] < rank[s]) == before:
            out += level.x[s].T @ level.slab(v, s + 1)
        return out

    def apply(r):
        y = np.zeros_like(r)
        for s in order:
            y[s * level.n:(s + 1) * level.n] = level.lu[s].solve(level.slab(r, s) - w * links(y, s, True))
        z = y.copy()
        for s in reversed(order[:-1]):
            z[s * level.n:(s + 1) * level.n] -= w * level.lu[s].solve(links(z, s, False))
        return z

    return apply


def main():
    a, b, n = load(sys.argv[1])
    weights = [float(w) for w in (sys.argv[2] if len(sys.argv) > 2 else "1,1.3,1.6").split(",")]
    level = Level(a, n)
    for name, order in orders(level.slabs).items():
        for w in weights:
            print(f"{name:9s} w = {w:.2f}: {pcg_iterations(a, b, ssor(level, order, w))} iterations", flush=True)


if __name__ == "__main__":
    main()
