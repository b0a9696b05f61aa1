#!/usr/bin/env python3
"""meshflow against the 2-D optical-flow tools on a closed shell no single projection covers.

The scene is ``examples/closed_shell.rs``'s: an ellipsoidal shell in an ``N^3`` stack
(``out/closed_shell/stack.npy``, ``(K, Z, Y, X)``, voxels 1 x 1 x 1 in the surface's units,
voxel ``(k, j, i)`` at ``(x, y, z) = (i, j, k)``) that turns about z by ``omega`` a frame and
deforms. The truth is the example's, re-implemented here: with ``c = ((N-1)/2,)*3``,
semi-axes ``A(t) = 0.36 N (1 + s t, 0.9, 0.8 (1 - s t))`` and ``Y = R(-omega t)(x - c)``, a
point ``x`` moves at ``v*(x, t) = R(omega t) (omega z^ x Y + Y * rate)``, ``rate = (s/(1 + s t),
0, -s/(1 - s t))`` (``OMEGA``, ``STRAIN`` from the environment as in the example, default
0.04 and 0.01).

The score is the example's ``score``: for slab ``s`` (frames ``s``, ``s+1``) at the vertices'
middle positions ``m = (X_s + X_s+1)/2`` of meshflow's tracked surface, with the angle-weighted
vertex normals ``n`` there and ``P = I - n n^T``: relative endpoint error
``sum |P v - P v*| / sum |P v*|`` (per slab, and pooled over all slabs: the number the example
prints) and the median (upper, as ``statistics::median``) of ``|P v| / |P v*|`` over the
vertices whose true tangential speed is at least a quarter of the slab's median.
meshflow's ``v`` is its ``velocity.npy`` (mesh motion plus flow); a 2-D tool's ``v`` is its
displacement from frame ``s`` to ``s+1`` (dt = 1), read at the image point ``q`` with
``q = pix(m) - d(q)/2`` (3 fixed-point steps: the material that is at ``m`` mid-slab) and
lifted to 3-D at ``m`` along the image's viewing ray (below) to the moving surface: the
tangent-plane vector plus the ray's part that gives it the mesh's own normal speed
``n.(X_s+1 - X_s)`` (``--lift tangent``: the tangent-plane vector alone, as compare.py). Only
the tangential part is scored; the normal speed matters where the ray is oblique.

The 2-D images, per frame (tools and their settings are compare.py's, imported; its image
constants are set to this stack's: pixel 1, meshflow sample's smoothing 2 and shell +-2):

* ``proj z`` / ``proj x``: the maximum of the volume along z (pixel (row, col) = (y, x)) or
  along x ((z, y)). Lifted along the viewing ray into the tangent plane at ``m``:
  ``t = (dx, dy, -(n_x dx + n_y dy)/n_z)`` (``|n_z|`` clamped to >= 0.1, as compare.py). Every
  ray crosses the shell twice, so a vertex on the far side gets the same pixel's flow: the
  projection's honest failure. Rotation about z is a rigid rotation of the z projection,
  the easiest case a projection can meet; ``proj x`` sees the front and back move opposite
  ways along y.
* ``chart +z`` / ``chart +x``: ONE azimuthal-equidistant chart (compare.SphereChart, pixel 1
  on the sphere fitted to frame 0's vertices) about +z or +x, out to the antipode
  (``theta <= 180 deg``, pixels beyond it black), so that it covers the whole shell; the
  antipode is the chart's rim circle. Each pixel is compare.pullback's maximum over 9
  samples within +-2 of that frame's surface along the ray, of the volume smoothed by
  sigma 2. A chart flow goes through the chart's Jacobian and along the radius into the
  tangent plane (compare.py's lift). About +z the turn is a rigid rotation of the chart;
  about +x the antipode (-x) moves at full speed.
* ``charts +-x``: two such charts about +x and -x, each out to 135 deg (out to 100 deg,
  Farneback's defaults score 0.35 instead of 0.20: the black beyond the chart's edge holds
  the flow near it); a vertex takes the chart whose centre is nearer (``theta <= 90 deg``):
  the most a 2-D user could do.
* ``volume`` (3-D ILK only): the volume itself.

Each tool runs with its defaults and compare.SWEEPS' settings; "tuned" is the setting with
the lowest pooled error, chosen on the truth it is scored on (an upper bound for the tool).
meshflow is run (CLI, unless its output is already in WORK) with its defaults and a few
settings; ``--example`` re-scores each meshflow run with the Rust example
(``SURFACE=.. FLOW=.. closed_shell N K``, which re-renders the stack: checked to be equal)
and shows its printed numbers beside ours.

Run (from the repository, the meshflow binary and the example built):

    cargo build --release --bin meshflow --example closed_shell
    mkdir -p /tmp/shellcmp && (cd /tmp/shellcmp && PATH/TO/meshflow/target/release/examples/closed_shell)
    PATH/TO/python examples/field_tools/shell.py /tmp/shellcmp/out/closed_shell/stack.npy \\
        --work /tmp/shellcmp --meshflow target/release/meshflow --example target/release/examples/closed_shell

Writes WORK/table.md (the table, and the defaults' error by region: where each image sees the
shell well or badly) and WORK/results.json (every setting, per slab); about 2 minutes on one
core, 25 s with --defaults-only. Options: ``--lift surface|tangent``, ``--defaults-only``
(no sweep), ``--images``, ``--methods`` (farneback,tvl1,ilk,piv,ilk3d), ``--jobs N`` (1).
"""

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import compare as cmp  # noqa: E402  (sets the BLAS threads to 1 too)
import numpy as np  # noqa: E402

# compare.py's images read these module constants (the zebrafish's um); this stack's voxels
# are 1 x 1 x 1, and meshflow sample's defaults are then a smoothing of 2 and a shell of +-2.
cmp.VOXEL, cmp.PIXEL, cmp.SHELL, cmp.SIGMA = np.ones(3), 1.0, 2.0, 2.0
SWEEPS = dict(cmp.SWEEPS, ilk3d=[dict(radius=15), dict(gaussian=True), dict(presmooth_um=cmp.SIGMA)])
METHODS = ["farneback", "tvl1", "ilk", "piv", "ilk3d"]
IMAGES = ["proj z", "proj x", "chart +z", "chart +x", "charts +-x"]
MESHFLOW_RUNS = [  # name, solve flags ("H" is replaced by the mean edge length)
    ("defaults", []),
    ("--large-motion", ["--large-motion"]),
    ("--spread 0.25", ["--spread", "0.25"]),
    ("--spread 1", ["--spread", "1"]),
    ("--spread 2", ["--spread", "2"]),
    ("--local-integration 1h", ["--local-integration", "1H"]),
    ("--local-integration 2h", ["--local-integration", "2H"]),
    ("--local-integration 3h", ["--local-integration", "3H"]),
    ("--regularizer strain", ["--regularizer", "strain"]),
]


# ----------------------------------------------------------------------------- truth, score


def rot_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def true_velocity(x, t, n, omega, strain):
    """closed_shell.rs's Scene::velocity at points x (M, 3), time t (frames)."""
    y = (x - (n - 1) / 2.0) @ rot_z(-omega * t).T
    rate = np.array([strain / (1 + strain * t), 0.0, -strain / (1 - strain * t)])
    turn = omega * np.c_[-y[:, 1], y[:, 0], np.zeros(len(y))]
    return (turn + y * rate) @ rot_z(omega * t).T


def vertex_normals(X, F):
    """meshflow's connection::vertex_normals: face normals summed with the corner angles."""
    x = X[F]
    fn = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    fn /= np.linalg.norm(fn, axis=1)[:, None]
    out = np.zeros_like(X)
    for c in range(3):
        a, b = x[:, (c + 1) % 3] - x[:, c], x[:, (c + 2) % 3] - x[:, c]
        angle = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), (a * b).sum(1))
        np.add.at(out, F[:, c], angle[:, None] * fn)
    return out / np.linalg.norm(out, axis=1)[:, None]


def tangential(v, n):
    return v - n * (v * n).sum(1)[:, None]


def upper_median(x):
    return float(np.sort(x)[len(x) // 2]) if len(x) else float("nan")


class Scorer:
    def __init__(self, X, F, n, omega, strain):
        self.mid = [(X[s] + X[s + 1]) / 2 for s in range(len(X) - 1)]
        self.normal = [vertex_normals(m, F) for m in self.mid]
        self.truth = [tangential(true_velocity(m, s + 0.5, n, omega, strain), nn)
                      for s, (m, nn) in enumerate(zip(self.mid, self.normal))]

    def score(self, velocity):
        """velocity: per slab (V, 3). Relative endpoint error per slab and pooled, speed ratio."""
        err, tru, ratios = [], [], []
        for v, t, nn in zip(velocity, self.truth, self.normal):
            v = tangential(v, nn)
            speed = np.linalg.norm(t, axis=1)
            err.append(np.linalg.norm(v - t, axis=1).sum())
            tru.append(speed.sum())
            moving = speed >= 0.25 * upper_median(speed)
            ratios.append(np.linalg.norm(v[moving], axis=1) / speed[moving])
        return {"slabs": [e / t for e, t in zip(err, tru)], "all": sum(err) / sum(tru),
                "speed": upper_median(np.concatenate(ratios))}


# ----------------------------------------------------------------------------- images

LIFT = {}  # "tangent": lift into the tangent plane only; per slab "normal" n, "speed" n.(X_s+1 - X_s)


class Panel:
    """One image sequence and how the slabs' middle positions m see it: pixel pix_of(m), and
    the lift of a flow d there to 3-D, t = lift d + normal, where normal (along the viewing
    ray) gives t the surface's own normal speed n.(X_s+1 - X_s) (LIFT; zero for --lift
    tangent and for 3-D). serves: per slab, the vertices this panel's flow is used for."""

    def __init__(self, images, pix_of, lifts, rays=None, serves=None):
        self.images, self.pix_of, self.lift, self.serves = images, pix_of, lifts, serves
        self.pix = [pix_of(m) for m in LIFT["mid"]]
        self.normal = [np.zeros_like(n) if rays is None or LIFT["tangent"] else
                       (w / np.maximum((r * n).sum(1), 0.1))[:, None] * r
                       for r, n, w in zip(rays or LIFT["normal"], LIFT["normal"], LIFT["speed"])]

    def vertices(self, s):
        return np.arange(len(self.pix[s])) if self.serves is None else np.flatnonzero(self.serves[s])

    def lifted(self, s, sel, d):
        return np.einsum("nij,nj->ni", self.lift[s][sel], d) + self.normal[s][sel]


def projection_panel(vols, scorer, axis):
    """Max projection along z (axis 0 of (Z, Y, X)) or x (axis 2), lifted along the ray."""
    images = np.stack([v.max(axis=axis) for v in vols])
    # image (row, col) -> 3-D components, and the ray's component
    rc, ray = ((1, 0), 2) if axis == 0 else ((2, 1), 0)
    lifts, rays = [], []
    for n in scorer.normal:
        rays.append(np.eye(3)[ray] * np.sign(n[:, [ray]]))
        nr = np.where(np.abs(n[:, ray]) < 0.1, np.copysign(0.1, n[:, ray]), n[:, ray])
        L = np.zeros((len(n), 3, 2))
        for k, comp in enumerate(rc):
            L[:, comp, k] = 1.0
            L[:, ray, k] = -n[:, comp] / nr
        lifts.append(L)
    return Panel(images, lambda q: q[:, list(rc)], lifts, rays)


def chart_panel(vols, X, scorer, centre, radius, axis, max_degrees, serves=None):
    """compare.py's pullback on an azimuthal-equidistant chart out to max_degrees."""
    reach = radius * np.radians(max_degrees)
    chart = cmp.SphereChart(centre, radius, axis, reach)
    rows, cols = np.mgrid[0 : chart.size, 0 : chart.size].astype(float)
    outside = np.hypot(rows - chart.c0, cols - chart.c0) * cmp.PIXEL > reach
    images = []
    for vol, Xk in zip(vols, X):
        img = cmp.pullback(vol, chart, cmp.shell_radius(chart, Xk))
        img[outside] = 0.0
        images.append(img)
    lifts, rays = [], []
    for m, n in zip(scorer.mid, scorer.normal):
        radial = (m - centre) / np.linalg.norm(m - centre, axis=1)[:, None]
        rays.append(radial)
        ray = np.eye(3)[None] - radial[:, :, None] * n[:, None, :] / (n * radial).sum(1)[:, None, None]
        lifts.append(np.einsum("nij,njk->nik", ray, chart.jacobian(m)))
    return Panel(np.stack(images), lambda q: chart.to_pixels(q.copy()), lifts, rays, serves)


def volume_panel(vols, scorer):
    L = np.zeros((3, 3))
    L[0, 2] = L[1, 1] = L[2, 0] = 1.0  # (dk, dj, di) -> (x, y, z)
    return Panel(vols, lambda q: q[:, ::-1], [np.broadcast_to(L, (len(m), 3, 3)) for m in scorer.mid])


def perfect_tool(panels, scorer, omega, strain, n):
    """What a tool would score that reports each vertex's own exact image motion
    pix(m + v*/2) - pix(m - v*/2), lifted as the tools' flows: the image's and lift's floor."""
    out = []
    for s, m in enumerate(scorer.mid):
        v, vt = np.zeros_like(m), true_velocity(m, s + 0.5, n, omega, strain)
        for p in panels:
            sel = p.vertices(s)
            v[sel] = p.lifted(s, sel, p.pix_of(m[sel] + vt[sel] / 2) - p.pix_of(m[sel] - vt[sel] / 2))
        out.append(v)
    return scorer.score(out)


def angle_from(axis, points, centre):
    w = points - centre
    return np.degrees(np.arccos(np.clip(w @ axis / np.linalg.norm(w, axis=1), -1, 1)))


# ----------------------------------------------------------------------------- tools


def tool_velocity(method, params, panels, n_slabs, n_vertices):
    """The tool's displacement per slab (V, 3), read at q = pix(m) - d(q)/2 and lifted."""
    out = []
    for s in range(n_slabs):
        v = np.zeros((n_vertices, 3))
        for p in panels:
            a, b = cmp.normalize_pair(p.images[s], p.images[s + 1])
            at = cmp._quietly(lambda: cmp.RUNNERS[method](a, b, params))
            sel = p.vertices(s)
            q, d = p.pix[s][sel], 0.0
            for _ in range(3):
                d = at(*(q - d / 2).T)
            v[sel] = p.lifted(s, sel, d)
        out.append(v)
    return out


JOB = {}  # filled before the workers fork


def region_errors(scorer, velocity):
    """Pooled relative error over each REGIONS part of the shell (the vertices' middles)."""
    out = {}
    for image, parts in JOB["regions"].items():
        for part, masks in parts.items():
            e = sum(np.linalg.norm(tangential(v, n)[k] - t[k], axis=1).sum()
                    for v, t, n, k in zip(velocity, scorer.truth, scorer.normal, masks))
            out[f"{image}: {part}"] = e / sum(np.linalg.norm(t[k], axis=1).sum() for t, k in zip(scorer.truth, masks))
    return out


def regions(scorer, centre):
    """Where each image sees the shell well or badly: the ray's angle to the surface for a
    projection, the angle from the chart's centre for a chart."""
    out = {}
    for image, k in (("proj z", 2), ("proj x", 0)):
        out[image] = {"facing (abs n.ray >= 0.3)": [np.abs(n[:, k]) >= 0.3 for n in scorer.normal],
                      "grazing (abs n.ray < 0.3)": [np.abs(n[:, k]) < 0.3 for n in scorer.normal]}
    for image, axis in (("chart +z", np.eye(3)[2]), ("chart +x", np.eye(3)[0])):
        th = [angle_from(axis, m, centre) for m in scorer.mid]
        out[image] = {"theta <= 90": [t <= 90 for t in th], "theta 90-135": [(t > 90) & (t <= 135) for t in th],
                      "theta > 135": [t > 135 for t in th]}
    return out


def run_group(key):
    method, image = key
    scorer, panels = JOB["scorer"], JOB["panels"][image]
    rows = []
    for change in [{}] + (SWEEPS[method] if JOB["sweep"] else []):
        t0 = time.time()
        try:
            v = tool_velocity(method, dict(cmp.DEFAULTS[method], **change), panels, len(scorer.mid), len(scorer.mid[0]))
            s = scorer.score(v)
            if not change:
                s["regions"] = region_errors(scorer, v)
        except Exception as e:  # a setting a tool refuses (a window larger than the image)
            s = {"error": f"{type(e).__name__}: {e}"}
        s.update(method=method, image=image, setting=cmp.setting_label(change), seconds=time.time() - t0)
        rows.append(s)
    return rows


# ----------------------------------------------------------------------------- meshflow


def meshflow_surface(args, work):
    """`meshflow surface` and `meshflow sample` as in closed_shell.rs's docs (kept if there)."""
    surf = work / "surf"
    if not (surf / "positions.npy").exists():
        meshflow(args, "surface", args.stack, "--shape", "closed", "--vertices", "4000", "--out", str(surf))
        meshflow(args, "sample", args.stack, str(surf))
    return surf


def meshflow_solves(args, work, surf, h):
    """`meshflow solve` with each of MESHFLOW_RUNS' flags (kept if there)."""
    flows = {}
    for name, flags in MESHFLOW_RUNS:
        flow = work / ("flow_" + re.sub(r"[^a-z0-9.]+", "_", name.strip("-")))
        flags = [f"{2 * h:.4g}" if f == "2H" else f for f in flags]
        if not (flow / "velocity.npy").exists():
            meshflow(args, "solve", str(surf), "--out", str(flow), "--force", *flags)
        flows[name] = (flow, " ".join(flags))
    return flows


def meshflow(args, *cmd):
    subprocess.run([args.meshflow, *cmd, "--quiet"], check=True, stdout=subprocess.DEVNULL)


def rust_score(example, stack_shape, stack, surf, flow):
    """The example's printed CLI score of this run (it re-renders the stack in a temp dir)."""
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, SURFACE=str(surf.resolve()), FLOW=str(flow.resolve()))
        out = subprocess.run([str(Path(example).resolve()), str(stack_shape[-1]), str(stack_shape[0])],
                             cwd=tmp, env=env, capture_output=True, text=True, check=True).stdout
        same = np.array_equal(np.load(Path(tmp) / "out/closed_shell/stack.npy"), stack)
    m = re.search(r"CLI: .*relative endpoint error ([\d.]+) %.*median speed ratio ([\d.]+)", out)
    return {"all": float(m.group(1)) / 100, "speed": float(m.group(2)), "same_stack": bool(same)}


# ----------------------------------------------------------------------------- main


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("stack", help="closed_shell's out/closed_shell/stack.npy")
    ap.add_argument("--work", default=".", help="meshflow's runs (surf, flow_*) and the results")
    ap.add_argument("--meshflow", default="meshflow", help="the meshflow binary")
    ap.add_argument("--example", help="the built closed_shell example: re-score meshflow's runs with it")
    ap.add_argument("--defaults-only", action="store_true", help="no sweep")
    ap.add_argument("--images", default=",".join(IMAGES))
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--lift", choices=["surface", "tangent"], default="surface",
                    help="a 2-D flow lifted along its ray to the moving surface (its normal speed, "
                         "default) or into the tangent plane (compare.py's)")
    ap.add_argument("--jobs", type=int, default=1)
    args = ap.parse_args()
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    t_start = time.time()
    omega, strain = float(os.environ.get("OMEGA", 0.04)), float(os.environ.get("STRAIN", 0.01))
    stack = np.load(args.stack)
    K, nz, ny, nx = stack.shape
    if not nz == ny == nx:
        raise SystemExit(f"{args.stack}: {stack.shape}; this script takes cubic voxels (Z_SCALE=1)")
    vols = stack.astype(np.float32)

    surf = meshflow_surface(args, work)
    X, F = np.load(surf / "positions.npy"), np.load(surf / "faces.npy").astype(np.int64)
    edges = np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1), axis=0)
    h = float(np.linalg.norm(X[0][edges[:, 0]] - X[0][edges[:, 1]], axis=1).mean())
    flows = meshflow_solves(args, work, surf, h)
    scorer = Scorer(X, F, nx, omega, strain)
    results = {"stack": list(stack.shape), "lift": args.lift, "omega": omega, "strain": strain, "mean_edge": h, "meshflow": {}, "tools": [], "coverage": {}}
    for name, (flow, flags) in flows.items():
        s = scorer.score(np.load(flow / "velocity.npy"))
        s["flags"] = flags
        if args.example:
            s["rust"] = rust_score(args.example, stack.shape, stack, surf, flow)
        results["meshflow"][name] = s
        rust = (f"; closed_shell prints {100 * s['rust']['all']:.1f} %, {s['rust']['speed']:.3f}"
                f"{'' if s['rust']['same_stack'] else ' (ITS STACK DIFFERS)'}" if "rust" in s else "")
        print(f"meshflow {name}: {100 * s['all']:.3f} %, speed {s['speed']:.4f}{rust}", file=sys.stderr)

    # images
    t0 = time.time()
    LIFT.update(tangent=args.lift == "tangent", normal=scorer.normal, mid=scorer.mid,
                speed=[(n * (X[s + 1] - X[s])).sum(1) for s, n in enumerate(scorer.normal)])
    centre, radius = cmp.fit_sphere(X[0])
    ex, ez = np.eye(3)[0], np.eye(3)[2]
    panels = {}
    images = [i for i in args.images.split(",") if i]
    for image in images:
        if image.startswith("proj"):
            panels[image] = [projection_panel(vols, scorer, 0 if image == "proj z" else 2)]
        elif image.startswith("chart "):
            panels[image] = [chart_panel(vols, X, scorer, centre, radius, ez if image == "chart +z" else ex, 180.0)]
        elif image == "charts +-x":
            front = [(m - centre) @ ex >= 0 for m in scorer.mid]
            panels[image] = [chart_panel(vols, X, scorer, centre, radius, ex, 135.0, front),
                             chart_panel(vols, X, scorer, centre, radius, -ex, 135.0, [~f for f in front])]
        else:
            raise SystemExit(f"unknown image {image!r}; known: {', '.join(IMAGES)}")
    panels["volume"] = [volume_panel(vols, scorer)]
    results["perfect_tool"] = {k: perfect_tool(p, scorer, omega, strain, nx) for k, p in panels.items() if k != "volume"}
    for k, r in results["perfect_tool"].items():
        print(f"a perfect tool on {k} would score {r['all']:.3f}, speed {r['speed']:.3f}", file=sys.stderr)
    print(f"images in {time.time() - t0:.1f} s; sphere R {radius:.2f}, mean edge {h:.3f}", file=sys.stderr)

    # coverage, area-weighted over frame 0's vertices
    x0 = X[0][F]
    area = np.zeros(len(X[0]))
    for c in range(3):
        np.add.at(area, F[:, c], np.linalg.norm(np.cross(x0[:, 1] - x0[:, 0], x0[:, 2] - x0[:, 0]), axis=1) / 6)
    area /= area.sum()
    n0 = vertex_normals(X[0], F)
    cov = results["coverage"]
    for name, k in (("proj z", 2), ("proj x", 0)):
        cov[name] = {"grazing |n.ray| < 0.3": float(area[np.abs(n0[:, k]) < 0.3].sum()),
                     "lift clamped |n.ray| < 0.1": float(area[np.abs(n0[:, k]) < 0.1].sum())}
    for name, axis in (("chart +z", ez), ("chart +x", ex)):
        th = np.radians(angle_from(axis, X[0], centre))
        stretch = th / np.maximum(np.sin(th), 1e-12)
        cov[name] = {"beyond 90 deg": float(area[th > np.pi / 2].sum()), "stretch > 1.5": float(area[stretch > 1.5].sum()),
                     "stretch > 3": float(area[stretch > 3].sum()), "stretch > 10": float(area[stretch > 10].sum())}
    for name, c in cov.items():
        print(f"coverage {name}: " + ", ".join(f"{k} {100 * v:.1f} %" for k, v in c.items()), file=sys.stderr)

    # the tools
    methods = [m for m in args.methods.split(",") if m and m not in cmp.MISSING]
    cmp.self_test(methods)
    JOB.update(scorer=scorer, panels=panels, sweep=not args.defaults_only, regions=regions(scorer, centre))
    results["region_share"] = {f"{i}: {p}": float(np.mean(np.concatenate(k))) for i, parts in JOB["regions"].items()
                               for p, k in parts.items() if i in images}
    for name, r in results["meshflow"].items():
        r["regions"] = region_errors(scorer, [v for v in np.load(flows[name][0] / "velocity.npy")])
    groups = [(m, "volume") if m == "ilk3d" else None for m in methods]
    groups = [g for g in groups if g] + [(m, i) for m in methods if m != "ilk3d" for i in images]
    t0 = time.time()
    if args.jobs > 1:
        from multiprocessing import get_context

        with get_context("fork").Pool(args.jobs) as pool:
            batches = pool.imap_unordered(run_group, groups)
            for rows in batches:
                results["tools"] += rows
                print(f"  {rows[0]['method']} on {rows[0]['image']}: {len(rows)} settings, {sum(r['seconds'] for r in rows):.0f} s", file=sys.stderr)
    else:
        for g in groups:
            rows = run_group(g)
            results["tools"] += rows
            print(f"  {g[0]} on {g[1]}: {len(rows)} settings, {sum(r['seconds'] for r in rows):.0f} s", file=sys.stderr)
    results["tools_seconds"] = time.time() - t0
    results["total_seconds"] = time.time() - t_start
    write_table(results, work, images)


def write_table(results, work, images):
    n_slabs = len(next(iter(results["meshflow"].values()))["slabs"])
    head = ["method", "image", "setting"] + [f"slab {s}" for s in range(n_slabs)] + ["all slabs", "speed ratio"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def row(method, image, setting, s):
        lines.append(f"| {method} | {image} | {setting} | " + " | ".join(f"{x:.3f}" for x in s["slabs"])
                     + f" | **{s['all']:.3f}** | {s['speed']:.3f} |")

    for name, s in results["meshflow"].items():
        row("meshflow", "surface", f"`{s['flags']}`" if s["flags"] else "defaults", s)
    names = {"farneback": "Farneback", "tvl1": "TV-L1", "ilk": "ILK", "piv": "OpenPIV", "ilk3d": "ILK 3-D"}
    for m in METHODS:
        for image in ["volume"] + images:
            sel = [r for r in results["tools"] if r["method"] == m and r["image"] == image and "all" in r]
            if not sel:
                continue
            d = [r for r in sel if r["setting"] == "defaults"]
            if d:
                row(names[m], image, "defaults", d[0])
            best = min(sel, key=lambda r: r["all"])
            if len(sel) > 1:
                label = "tuned: defaults are best" if best["setting"] == "defaults" else f"tuned: `{best['setting']}`"
                row(names[m], image, label, best)
    for image, s in results["perfect_tool"].items():
        row("perfect 2-D tool", image, "each vertex's own image motion", s)
    # the defaults by region: where each image sees the shell well, and where not
    cols = [("meshflow defaults", results["meshflow"].get("defaults"))] + [
        (f"{names[m]} defaults", None) for m in METHODS if m != "ilk3d"]
    lines += ["", "By region (pooled error of the defaults over the vertices in each part of the shell; "
              "each tool on the image the part belongs to):", "",
              "| image: part | vertices | " + " | ".join(c for c, _ in cols) + " |", "|" + "---|" * (len(cols) + 2)]
    share = results["region_share"]
    for key in share:
        image = key.split(":")[0]
        cells = []
        for c, s in cols:
            if s is None:
                m = [k for k, v in names.items() if c.startswith(v + " ")][0]
                d = [r for r in results["tools"] if r["method"] == m and r["image"] == image and r["setting"] == "defaults"]
                s = d[0] if d and "regions" in d[0] else None
            cells.append(f"{s['regions'][key]:.3f}" if s else "")
        lines.append(f"| {key} | {100 * share[key]:.0f} % | " + " | ".join(cells) + " |")
    errors = [f"{r['method']} {r['image']} `{r['setting']}`: {r['error']}" for r in results["tools"] if "error" in r]
    text = ("Relative tangential endpoint error Σ|v−v*|/Σ|v*| over the vertices (per slab and pooled "
            "over all slabs, as closed_shell prints), and the median speed ratio |v|/|v*|.\n\n" + "\n".join(lines) + "\n")
    if any("rust" in s for s in results["meshflow"].values()):
        text += "\nclosed_shell's own score of the same meshflow runs: " + "; ".join(
            f"{n} {100 * s['rust']['all']:.1f} % / {s['rust']['speed']:.3f}" for n, s in results["meshflow"].items() if "rust" in s) + "\n"
    text += "\ncoverage (area of frame 0's surface): " + "; ".join(
        f"{k}: " + ", ".join(f"{a} {100 * v:.0f} %" for a, v in c.items()) for k, c in results["coverage"].items()) + "\n"
    if errors:
        text += "\nsettings a tool refused: " + "; ".join(errors) + "\n"
    text += f"\ntools {results['tools_seconds']:.0f} s, total {results['total_seconds']:.0f} s\n"
    print(text)
    (work / "table.md").write_text(text)
    (work / "results.json").write_text(json.dumps(results, indent=1, default=str))
    print(f"wrote {work}/table.md, results.json", file=sys.stderr)


if __name__ == "__main__":
    main()
