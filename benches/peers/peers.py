"""The mass-spring benchmark of `lancet bench --preset damped` in Taichi and NVIDIA Warp, beside
lancet's own rows, in one run on one machine.

The configuration (the one Warp, Newton and Taichi users know): a box of five-tet cells as
`warp.sim`'s `add_soft_grid` splits them, cells of 5 cm, a spring on every unique tet edge of
stiffness 5e4 N/m (and 5 N s/m of damping along it for `damped`), 0.125 kg per node, the nodes
of the face x = 0 fixed, gravity, dt 2e-4 s, symplectic Euler, float32. Sizes: 40x20x20 cells
(18,081 nodes, 102,080 springs) and 72x36x36 (99,937 nodes, 579,456 springs).

Each peer runs the fastest plain kernel of its kind: Taichi gathers each node's springs from a
CSR adjacency (one parallel loop over nodes, on the threads given), Warp does the same in one
kernel (Warp's CPU backend runs a launch on one thread). Both then integrate in a second
kernel. Run through `run.sh`, which installs the peers in a virtual environment.

Two ways to time them. By default (`--rounds`), each engine runs in its own process in turn,
lancet's through `lancet bench --preset`, and ratios are taken round by round. With
`--paired N`, lancet's fast engine steps in this process through its Python package
(`lancet.World.preset`, stepped unchecked as `lancet bench` steps it), every engine in turn N
times, and ratios are taken chunk by chunk.
"""

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

CELL = 0.05
STIFFNESS = 5e4
DAMPING = 5.0
MASS = 0.125
DT = 2e-4
GRAVITY_Z = -9.81
GRIDS = {"small": (40, 20, 20), "large": (72, 36, 36)}


def soft_grid(nx, ny, nz):
    """Node positions and tets of warp.sim's add_soft_grid (five tets per cell, alternating)."""
    xs, ys, zs = np.meshgrid(
        np.arange(nx + 1), np.arange(ny + 1), np.arange(nz + 1), indexing="ij"
    )
    # Index (x, y, z) -> (nx + 1) (ny + 1) z + (nx + 1) y + x, as add_soft_grid numbers them.
    pos = np.zeros(((nx + 1) * (ny + 1) * (nz + 1), 3))
    idx = (nx + 1) * (ny + 1) * zs + (nx + 1) * ys + xs
    pos[idx.ravel(), 0] = xs.ravel() * CELL
    pos[idx.ravel(), 1] = ys.ravel() * CELL
    pos[idx.ravel(), 2] = zs.ravel() * CELL

    def g(x, y, z):
        return (nx + 1) * (ny + 1) * z + (nx + 1) * y + x

    tets = []
    for z in range(nz):
        for y in range(ny):
            for x in range(nx):
                v0, v1, v2, v3 = g(x, y, z), g(x + 1, y, z), g(x + 1, y, z + 1), g(x, y, z + 1)
                v4, v5, v6, v7 = (
                    g(x, y + 1, z),
                    g(x + 1, y + 1, z),
                    g(x + 1, y + 1, z + 1),
                    g(x, y + 1, z + 1),
                )
                if (x & 1) ^ (y & 1) ^ (z & 1):
                    tets += [(v0, v1, v4, v3), (v2, v3, v6, v1), (v5, v4, v1, v6),
                             (v7, v6, v3, v4), (v4, v1, v6, v3)]
                else:
                    tets += [(v1, v2, v5, v0), (v3, v0, v7, v2), (v4, v7, v0, v5),
                             (v6, v5, v2, v7), (v5, v2, v7, v0)]
    return pos, np.array(tets, dtype=np.int64)


def springs_and_csr(pos, tets):
    """Unique tet edges, and each node's springs as a CSR adjacency (neighbour, rest length)."""
    pairs = np.concatenate([tets[:, [a, b]] for a, b in
                            [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]])
    pairs.sort(axis=1)
    edges = np.unique(pairs, axis=0)
    rest = np.linalg.norm(pos[edges[:, 1]] - pos[edges[:, 0]], axis=1)
    both = np.concatenate([edges, edges[:, ::-1]])
    both_rest = np.concatenate([rest, rest])
    order = np.lexsort((both[:, 1], both[:, 0]))
    both, both_rest = both[order], both_rest[order]
    row = np.zeros(len(pos) + 1, dtype=np.int32)
    np.add.at(row, both[:, 0] + 1, 1)
    row = np.cumsum(row).astype(np.int32)
    return edges, row, both[:, 1].astype(np.int32), both_rest.astype(np.float32)


# Steps per timed chunk, as `lancet bench` times them (its `chunk`).
CHUNK = 20


def time_steps(step, sync, steps, repeats):
    """Seconds per step: the median chunk of `CHUNK` steps over `repeats` runs of `steps` steps,
    after a warm-up. The statistic `lancet bench` reports for lancet's rows (the median of its
    chunks of 20 steps), so that a stall of the shared machine is left out of both sides alike."""
    step(10)
    sync()
    times = []
    for _ in range(repeats):
        done = 0
        while done < steps:
            n = min(CHUNK, steps - done)
            t = time.perf_counter()
            step(n)
            sync()
            times.append((time.perf_counter() - t) / n)
            done += n
    return sorted(times)[len(times) // 2]


def setup_taichi(pos, row, col, rest, damping, threads):
    """Taichi's node gather on `threads` CPU threads: (step(k), sync(), positions(), close())."""
    import taichi as ti

    ti.init(arch=ti.cpu, cpu_max_num_threads=threads, default_fp=ti.f32, log_level=ti.ERROR)
    n = len(pos)
    x = ti.Vector.field(3, ti.f32, n)
    v = ti.Vector.field(3, ti.f32, n)
    v_next = ti.Vector.field(3, ti.f32, n)
    inv_m = ti.field(ti.f32, n)
    row_f = ti.field(ti.i32, n + 1)
    col_f = ti.field(ti.i32, len(col))
    rest_f = ti.field(ti.f32, len(col))
    x.from_numpy(pos.astype(np.float32))
    inv_m.from_numpy(np.where(pos[:, 0] < 1e-9, 0.0, 1.0 / MASS).astype(np.float32))
    row_f.from_numpy(row)
    col_f.from_numpy(col)
    rest_f.from_numpy(rest)
    c = float(damping)

    @ti.kernel
    def forces():
        for i in range(n):
            xi, vi = x[i], v[i]
            f = ti.Vector([0.0, 0.0, GRAVITY_Z * MASS])
            for e in range(row_f[i], row_f[i + 1]):
                j = col_f[e]
                d = x[j] - xi
                length = d.norm()
                u = d / length
                f += (STIFFNESS * (length - rest_f[e]) + c * (v[j] - vi).dot(u)) * u
            v_next[i] = vi + DT * inv_m[i] * f

    @ti.kernel
    def integrate():
        for i in range(n):
            v[i] = v_next[i]
            x[i] += DT * v_next[i]

    def step(k):
        for _ in range(k):
            forces()
            integrate()

    return step, ti.sync, x.to_numpy, ti.reset


def run_taichi(pos, row, col, rest, damping, threads, steps, repeats):
    step, sync, positions, close = setup_taichi(pos, row, col, rest, damping, threads)
    s = time_steps(step, sync, steps, repeats)
    out = positions()
    close()
    return s, out


def setup_warp(pos, row, col, rest, damping):
    """Warp's node gather on its CPU device (one thread): (step(k), sync(), positions(), close())."""
    import warp as wp

    wp.config.quiet = True
    wp.init()
    dev = "cpu"
    n = len(pos)

    @wp.kernel
    def forces(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
               v_next: wp.array(dtype=wp.vec3), inv_m: wp.array(dtype=float),
               row: wp.array(dtype=int), col: wp.array(dtype=int),
               rest: wp.array(dtype=float), c: float):
        i = wp.tid()
        xi = x[i]
        vi = v[i]
        f = wp.vec3(0.0, 0.0, GRAVITY_Z * MASS)
        for e in range(row[i], row[i + 1]):
            j = col[e]
            d = x[j] - xi
            length = wp.length(d)
            u = d / length
            f = f + (STIFFNESS * (length - rest[e]) + c * wp.dot(v[j] - vi, u)) * u
        v_next[i] = vi + DT * inv_m[i] * f

    @wp.kernel
    def integrate(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
                  v_next: wp.array(dtype=wp.vec3)):
        i = wp.tid()
        v[i] = v_next[i]
        x[i] = x[i] + DT * v_next[i]

    x = wp.array(pos.astype(np.float32), dtype=wp.vec3, device=dev)
    v = wp.zeros(n, dtype=wp.vec3, device=dev)
    v_next = wp.zeros(n, dtype=wp.vec3, device=dev)
    inv_m = wp.array(np.where(pos[:, 0] < 1e-9, 0.0, 1.0 / MASS).astype(np.float32),
                     dtype=float, device=dev)
    row_w = wp.array(row, dtype=int, device=dev)
    col_w = wp.array(col, dtype=int, device=dev)
    rest_w = wp.array(rest, dtype=float, device=dev)

    def step(k):
        for _ in range(k):
            wp.launch(forces, dim=n, inputs=[x, v, v_next, inv_m, row_w, col_w, rest_w,
                                             float(damping)], device=dev)
            wp.launch(integrate, dim=n, inputs=[x, v, v_next], device=dev)

    return step, wp.synchronize, x.numpy, lambda: None


def run_warp(pos, row, col, rest, damping, steps, repeats):
    step, sync, positions, _ = setup_warp(pos, row, col, rest, damping)
    s = time_steps(step, sync, steps, repeats)
    return s, positions()


def run_lancet(binary, preset, steps, split):
    cmd = [binary, "bench", "--preset", preset, "--engine", "reference,fast",
           "--split", split, "--steps", str(steps), "--json"]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    return json.loads(out)["rows"]


def one_round(args, grids, sizes, peers, damping):
    """Every engine once, peers first then lancet: {(size, nodes, springs, name): s/step}."""
    out = {}
    for size in sizes:
        pos, row, col, rest, n, m = grids[size]
        if "taichi" in peers:
            s, _ = run_taichi(pos, row, col, rest, damping, args.threads, args.steps,
                              args.repeats)
            out[(size, n, m, f"taichi node gather, {args.threads} threads")] = s
        if "warp" in peers:
            s, _ = run_warp(pos, row, col, rest, damping, args.steps, args.repeats)
            out[(size, n, m, "warp cpu node gather (one thread)")] = s
    for row_ in run_lancet(args.lancet, args.preset, args.steps, "five"):
        cells = row_["mesh"].split("-")[0]
        size = next((k for k, g in GRIDS.items() if "x".join(map(str, g)) == cells), cells)
        if size in sizes:
            out[(size, row_["nodes"], row_["springs"], "lancet " + row_["engine"])] = \
                row_["ms_per_step"] / 1e3
    return out


def quantile(xs, q):
    """The `q` quantile of `xs`, the nearest rank."""
    xs = sorted(xs)
    return xs[round(q * (len(xs) - 1))]


def paired(args, grids, sizes, peers, damping):
    """Every engine in this one process, lancet's through its Python package, stepped
    `CHUNK` steps at a time in turn (the order rotated each pair), `args.paired` times: each
    ratio compares chunks taken within a fraction of a second of each other, so the shared
    machine's drift from minute to minute leaves it alone."""
    try:
        import lancet
    except ImportError as e:
        sys.exit(f"--paired steps lancet through its Python package, which did not import "
                 f"({e}): run through benches/peers/run.sh, which builds it")
    preset = "damped" if damping else "undamped"
    for size in sizes:
        pos, row, col, rest, n, m = grids[size]
        engines, closers = {}, []
        # lancet's fast engine only: the float64 engine runs on one thread, and a core left
        # idle meanwhile is handed elsewhere by the host, which slows whatever runs next.
        world = lancet.World.preset(preset, size, "five", "fast")
        if world.node_count != n:
            sys.exit(f"lancet's {size} box has {world.node_count} nodes, the peers' {n}")
        engines["lancet fast"] = (lambda k: world.run(k, check=False), lambda: None)
        if "taichi" in peers:
            step, sync, _, close = setup_taichi(pos, row, col, rest, damping, args.threads)
            engines[f"taichi node gather, {args.threads} threads"] = (step, sync)
            closers.append(close)
        if "warp" in peers:
            step, sync, _, close = setup_warp(pos, row, col, rest, damping)
            engines["warp cpu node gather (one thread)"] = (step, sync)
            closers.append(close)
        names = list(engines)
        for step, sync in engines.values():
            step(10)
            sync()
        times = {k: [] for k in names}
        for p in range(args.paired):
            for k in names[p % len(names):] + names[:p % len(names)]:
                step, sync = engines[k]
                # Untimed first: the engine before left its own data in the caches, and its
                # thread pool spinning on the cores for a while before it sleeps. A simulator
                # steps one engine on and on, which is what the timed chunk then sees.
                step(CHUNK)
                sync()
                t = time.perf_counter()
                step(CHUNK)
                sync()
                times[k].append((time.perf_counter() - t) / CHUNK)
        for close in closers:
            close()
        print(f"# {size}: {n} nodes, {m} springs, {preset}; {args.paired} chunks of {CHUNK} "
              f"steps each, engines in turn")
        print(f"{'engine':<40} {'steps/s':>9} {'ms/step':>8}  steps/s p10-p90")
        for k in names:
            s = median(times[k])
            print(f"{k:<40} {1.0 / s:>9.0f} {s * 1e3:>8.3f}  "
                  f"{1.0 / quantile(times[k], 0.9):.0f}-{1.0 / quantile(times[k], 0.1):.0f}")
        fast = times["lancet fast"]
        for k in names[1:]:
            r = [b / a for a, b in zip(fast, times[k])]
            print(f"# {size}: lancet fast against {k}: {median(r):.2f}x, chunk by chunk "
                  f"(p10 {quantile(r, 0.1):.2f}, p25 {quantile(r, 0.25):.2f}, "
                  f"p75 {quantile(r, 0.75):.2f}, p90 {quantile(r, 0.9):.2f})")


def median(xs):
    xs = sorted(xs)
    return xs[len(xs) // 2] if len(xs) % 2 else 0.5 * (xs[len(xs) // 2 - 1] + xs[len(xs) // 2])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lancet", default="target/release/lancet", help="the lancet binary")
    ap.add_argument("--preset", choices=["damped", "undamped"], default="damped")
    ap.add_argument("--sizes", default="small,large", help="small, large or both")
    ap.add_argument("--threads", type=int, default=os.cpu_count(),
                    help="Taichi's CPU threads (lancet's fast engine uses every core)")
    ap.add_argument("--steps", type=int, default=200, help="steps per timed run")
    ap.add_argument("--repeats", type=int, default=5,
                    help="timed runs of --steps steps each (the median chunk of 20 steps over "
                         "all of them is shown; lancet's rows time one run)")
    ap.add_argument("--rounds", type=int, default=1,
                    help="rounds of every engine in turn (a shared machine's speed drifts by "
                         "a quarter from one minute to the next: with several rounds each "
                         "row shows the median round and the range, and lancet's fast engine "
                         "is compared with each peer round by round)")
    ap.add_argument("--peers", default="taichi,warp")
    ap.add_argument("--paired", type=int, default=0, metavar="N",
                    help="instead of rounds: N chunks of 20 steps of every engine in turn, all "
                         "in this process (lancet's fast engine through its Python package), "
                         "and each ratio taken chunk by chunk (--rounds, --steps, --repeats "
                         "and --lancet are then unused)")
    args = ap.parse_args()
    damping = DAMPING if args.preset == "damped" else 0.0
    sizes = [s for s in args.sizes.split(",") if s]
    peers = [p for p in args.peers.split(",") if p]
    grids = {}
    for size in sizes:
        pos, tets = soft_grid(*GRIDS[size])
        edges, row, col, rest = springs_and_csr(pos, tets)
        grids[size] = (pos, row, col, rest, len(pos), len(edges))
        print(f"# {size}: {GRIDS[size]} cells, {len(pos)} nodes, {len(edges)} springs",
              file=sys.stderr)
    if args.paired:
        paired(args, grids, sizes, peers, damping)
        return
    rounds = [one_round(args, grids, sizes, peers, damping) for _ in range(args.rounds)]
    keys = sorted(rounds[0], key=lambda k: (k[0] != "small", median([r[k] for r in rounds])))
    several = args.rounds > 1
    span = "  steps/s per round (min-max)" if several else ""
    print(f"{'size':<6} {'nodes':>7} {'springs':>8}  {'engine':<40} {'steps/s':>9} "
          f"{'ms/step':>8}{span}")
    for k in keys:
        size, n, m, name = k
        s = median([r[k] for r in rounds])
        rng = ""
        if several:
            rates = [1.0 / r[k] for r in rounds]
            rng = f"  {min(rates):.0f}-{max(rates):.0f}"
        print(f"{size:<6} {n:>7} {m:>8}  {name:<40} {1.0 / s:>9.0f} {s * 1e3:>8.3f}{rng}")
    # lancet's fast engine against every other engine, the ratio taken within each round.
    for size in sizes:
        fast = [k for k in keys if k[0] == size and "fast" in k[3]]
        if not fast:
            continue
        for k in keys:
            if k[0] != size or k == fast[0]:
                continue
            ratios = [r[k] / r[fast[0]] for r in rounds]
            each = ", ".join(f"{x:.2f}" for x in ratios)
            print(f"# {size}: lancet fast against {k[3]}: {median(ratios):.2f}x "
                  f"(round by round: {each})")


if __name__ == "__main__":
    main()
