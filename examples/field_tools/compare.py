#!/usr/bin/env python3
"""meshflow against the 2-D optical-flow tools microscopists use, on the zebrafish recording.

Scores OpenCV Farneback, scikit-image TV-L1 (``optical_flow_tvl1``) and ILK
(``optical_flow_ilk``, in 2-D and in 3-D on the volume) and OpenPIV cross-correlation on two
2-D images per frame, and meshflow's own flow, at the tracked cells with the scorer of
``meshflow solve --ground-truth-tracks`` (``src/accuracy/tracks.rs``), re-implemented here:

* a tracked cell at ``p`` (frame 0) and ``p'`` (frame 1) sits at the surface point ``xi``
  closest to ``p`` on frame 0's meshflow surface (face and barycentric coordinates);
  ``n`` is that face's unit normal, ``P = I - n n^T``, ``m = x_1(xi) - x_0(xi)`` the mesh's
  own motion there;
* truth ``r = P (p' - p - m)``; a meshflow flow ``u`` gives ``r^ = P dt u(xi)``; a tool's
  3-D displacement ``t`` (its image motion lifted to the surface, below) gives
  ``r^ = P (t - m)`` -- the EPE ``|r^ - r| = |P t - P (p' - p)|`` is the absolute one, and the
  denominator (the zero flow's ``|r|``) is meshflow's;
* endpoint ratio = mean ``|r^ - r|`` / mean ``|r|``; median speed ratio ``|r^|/|r|`` and
  direction error over the cells with ``|r|`` >= 10 % of the largest (lower medians).

The 2-D images, per frame:

* ``proj``: the maximum of the volume along z (pixels 1.6774 um, pixel (j, i) at
  (1.6774 i, 1.6774 j) um). A flow ``(dx, dy)`` there is lifted to the surface *along the
  viewing ray*: the tangent vector at ``xi`` whose xy part is ``(dx, dy)``,
  ``t = (dx, dy, -(n_x dx + n_y dy) / n_z)`` -- the exact inverse of the orthographic
  projection of a motion along the surface (``--lift tangential`` takes ``P (dx, dy, 0)``
  instead, which shortens the foreshortened component once more).
* ``pull``: a spherical pullback of the bright layer. The sphere is the reference sphere
  meshflow's surface is a height over (``surface.json``; a sphere fitted to frame 0's
  vertices by algebraic least squares if there is none); the chart is *azimuthal
  equidistant* about the cells' mean direction from its centre (radial scale 1, azimuthal
  scale ``theta / sin theta``: 1.13 at 49 deg, 1.55 at the 89 deg the outermost cells reach;
  latitude/longitude or stereographic charts stretch the rim more), pixels of 1.6774 um on
  the sphere. Each pixel is the maximum over 9 samples along its ray within +-14.3694 um
  (meshflow's default shell, 2 z-voxels) of the volume smoothed by a Gaussian of sigma
  3.3548 um (meshflow's default), trilinear, voxel (k, j, i) at (1.6774 i, 1.6774 j,
  7.1847 k) um, 0 outside the stack. The shell is centred on each frame's meshflow surface
  along the ray (``--pullback surface``, the default, as ``meshflow sample`` centres it on
  the mesh): the embryo is no sphere (the surface lies -30...+20 um from it at the 5th/95th
  percentiles on 140-141), and a shell about the sphere itself (``--pullback sphere``) misses
  a third of the cells there; ``--pullback surface0`` centres both frames' shells on frame
  0's surface. A chart flow is mapped through the chart's Jacobian at ``xi`` (on the sphere
  of radius ``|xi - c|``) and lifted along the ray into the surface's tangent plane.
* ``vol`` (3-D ILK only): the volume itself; its flow (voxels) scaled to um and projected
  with ``P``.

Every tool is evaluated at ``xi`` (bilinear / trilinear), as meshflow's flow is.

Run (the meshflow commands first, as in docs/guide.md; P is the meshflow binary):

    python3 examples/zebrafish/convert_ofish.py PATH/TO/ofish/data/cxcr4aMO2_290112 /tmp/zf
    mkdir -p /tmp/fieldcmp && cd /tmp/fieldcmp
    for pair in 114-116 120-122 140-141 140-142; do
        $P surface /tmp/zf/$pair/cells --out surf_$pair --vertices 65000
        $P sample /tmp/zf/$pair/volumes surf_$pair --voxel-size 1.6774,1.6774,7.1847
        $P match /tmp/zf/$pair/cells --out tracks_$pair.npy
        $P solve surf_$pair --out flow_$pair --regularizer strain --time-scale 0 \\
            --ground-truth-tracks tracks_$pair.npy
    done
    python3 examples/field_tools/compare.py /tmp/zf --work /tmp/fieldcmp --sweep

``--work DIR`` holds ``surf_{pair}``, ``tracks_{pair}.npy`` and ``flow_{pair}``
(``--surface``, ``--tracks``, ``--flow`` set other patterns, ``{pair}`` replaced). Options:

    --defaults-only / --sweep       each tool's defaults only (default), or also a sweep of
                                    about a dozen settings per tool and image
    --meshflow-flow NAME=PATTERN    score another meshflow run (several allowed), e.g.
                                    --meshflow-flow lm=/tmp/fieldcmp/flow_lm_{pair}; its
                                    surface is read from the run's meshflow_run.json, or
                                    NAME=FLOWPATTERN@SURFACEPATTERN
    --methods farneback,tvl1,ilk,piv,ilk3d   (default all available)
    --no-3d                         skip 3-D ILK (about 3 min of one core a pair; cached
                                    in OUT/cache once run)
    --sweep-3d                      with --sweep, also 3 settings of 3-D ILK (about 20 min)
    --lift ray|tangential           projection flow onto the surface (above)
    --pullback surface|surface0|sphere   where the pullback's shell is centred (above)
    --jobs N                        worker processes (default 2)
    --out DIR                       results.json, table.md, cached images (default WORK/field_tools)

Needs numpy and scipy; opencv-python-headless, scikit-image and openpiv are optional (a
missing one is reported and its columns skipped). Run time on 2 cores: --defaults-only --no-3d
about 1.5 min; --sweep about 15 min once 3-D ILK is cached (28 min before); see README.md.
"""

import argparse
import json
import os
import re
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from scipy import ndimage  # noqa: E402
from scipy.interpolate import RegularGridInterpolator  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402

VOXEL = np.array([1.6774, 1.6774, 7.1847])  # x, y, z in um
PIXEL = VOXEL[0]
SHELL = 2 * VOXEL.max()  # meshflow sample's default shell, +-14.3694 um
LAYERS = 9
SIGMA = 2 * VOXEL.min()  # meshflow sample's default smoothing, 3.3548 um
MOVING_FRACTION = 0.1
PAIRS = ["114-116", "120-122", "140-141", "140-142"]

MISSING = {}
try:
    import cv2

    cv2.setNumThreads(1)
except ImportError as e:  # pragma: no cover
    cv2 = None
    MISSING["farneback"] = f"opencv-python(-headless) not importable ({e})"
try:
    from skimage.registration import optical_flow_ilk, optical_flow_tvl1
except ImportError as e:  # pragma: no cover
    optical_flow_ilk = optical_flow_tvl1 = None
    for m in ("tvl1", "ilk", "ilk3d"):
        MISSING[m] = f"scikit-image not importable ({e})"
try:
    from openpiv import filters as piv_filters
    from openpiv import pyprocess as piv_pyprocess
    from openpiv import validation as piv_validation
except ImportError as e:  # pragma: no cover
    piv_pyprocess = None
    MISSING["piv"] = f"openpiv not importable ({e})"


# ----------------------------------------------------------------------------- geometry


def natural_key(path):
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", str(path))]


def closest_on_triangles(p, a, b, c):
    """Closest points of points p (M,3) on triangles (a, b, c) (M,3 each), and barycentrics
    (Ericson, Real-Time Collision Detection 5.1.5), vectorized."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(1), (ac * ap).sum(1)
    bp = p - b
    d3, d4 = (ab * bp).sum(1), (ac * bp).sum(1)
    cp = p - c
    d5, d6 = (ab * cp).sum(1), (ac * cp).sum(1)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    m = len(p)
    bary = np.zeros((m, 3))
    done = np.zeros(m, bool)

    def take(mask, w):
        nonlocal done
        mask = mask & ~done
        bary[mask] = w[mask] if w.ndim == 2 else w
        done |= mask

    ones = np.ones(m)
    zeros = np.zeros(m)
    take((d1 <= 0) & (d2 <= 0), np.stack([ones, zeros, zeros], 1))
    take((d3 >= 0) & (d4 <= d3), np.stack([zeros, ones, zeros], 1))
    take((d6 >= 0) & (d5 <= d6), np.stack([zeros, zeros, ones], 1))
    with np.errstate(divide="ignore", invalid="ignore"):
        v = d1 / (d1 - d3)
        take((vc <= 0) & (d1 >= 0) & (d3 <= 0), np.stack([1 - v, v, zeros], 1))
        w = d2 / (d2 - d6)
        take((vb <= 0) & (d2 >= 0) & (d6 <= 0), np.stack([1 - w, zeros, w], 1))
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        take((va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0), np.stack([zeros, 1 - w, w], 1))
        denom = 1.0 / (va + vb + vc)
        v, w = vb * denom, vc * denom
        take(np.ones(m, bool), np.stack([1 - v - w, v, w], 1))
    q = bary[:, :1] * a + bary[:, 1:2] * b + bary[:, 2:] * c
    return q, bary


def locate(points, X, F):
    """The closest point of the triangle mesh (X, F) to each point: face, barycentrics, point.
    Exact: every face with a corner within (nearest-vertex distance + longest edge) is tried."""
    tree = cKDTree(X)
    edges = np.concatenate([X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 1]], X[F[:, 0]] - X[F[:, 2]]])
    longest = np.sqrt((edges**2).sum(1)).max()
    order = np.argsort(F.ravel(), kind="stable")
    starts = np.searchsorted(F.ravel()[order], np.arange(len(X) + 1))
    faces_of = lambda v: order[starts[v] : starts[v + 1]] // 3  # noqa: E731
    d0, _ = tree.query(points)
    out_face = np.empty(len(points), int)
    out_bary = np.empty((len(points), 3))
    out_q = np.empty((len(points), 3))
    for i, (p, d) in enumerate(zip(points, d0)):
        verts = tree.query_ball_point(p, d + longest + 1e-9)
        cand = np.unique(np.concatenate([faces_of(v) for v in verts]))
        tri = X[F[cand]]
        q, bary = closest_on_triangles(np.repeat(p[None], len(cand), 0), tri[:, 0], tri[:, 1], tri[:, 2])
        best = np.argmin(((q - p) ** 2).sum(1))
        out_face[i], out_bary[i], out_q[i] = cand[best], bary[best], q[best]
    return out_face, out_bary, out_q


def lower_median(x):
    x = np.sort(np.asarray(x)[~np.isnan(x)])
    return float(x[(len(x) - 1) // 2]) if len(x) else float("nan")


class Scorer:
    """meshflow's track scorer (src/accuracy/tracks.rs) for one pair of frames."""

    def __init__(self, surface_dir, tracks_path):
        surface_dir = Path(surface_dir)
        self.X = np.load(surface_dir / "positions.npy")
        self.F = np.load(surface_dir / "faces.npy").astype(np.int64)
        times_file = surface_dir / "times.txt"
        times = np.loadtxt(times_file).ravel() if times_file.exists() else np.arange(len(self.X))
        if len(self.X) != 2:
            raise SystemExit(f"{surface_dir}: {len(self.X)} frames; this script scores pairs")
        self.dt = float(times[1] - times[0])
        tracks = np.load(tracks_path)
        if tracks.ndim != 3 or tracks.shape[0] != 2 or tracks.shape[2] != 3:
            raise SystemExit(f"{tracks_path}: shape {tracks.shape}, expected (2, N, 3)")
        both = np.isfinite(tracks).all(axis=2).all(axis=0)
        self.track_ids = np.flatnonzero(both)
        self.p0, self.p1 = tracks[0, both], tracks[1, both]
        self.face, self.bary, self.xi = locate(self.p0, self.X[0], self.F)
        corners = self.F[self.face]
        a, b, c = (self.X[0][corners[:, k]] for k in range(3))
        n = np.cross(b - a, c - a)
        self.normal = n / np.linalg.norm(n, axis=1)[:, None]
        self.P = np.eye(3)[None] - self.normal[:, :, None] * self.normal[:, None, :]
        x1 = (self.bary[:, :, None] * self.X[1][corners]).sum(1)
        self.mesh_motion = x1 - self.xi
        self.truth = self.tangential(self.p1 - self.p0 - self.mesh_motion)
        self.distance = np.linalg.norm(self.p0 - self.xi, axis=1)

    def tangential(self, v):
        return np.einsum("nij,nj->ni", self.P, v)

    def at_xi(self, per_vertex):
        """A per-vertex field of frame 0 interpolated at xi (barycentric)."""
        return (self.bary[:, :, None] * per_vertex[self.F[self.face]]).sum(1)

    def score_velocity(self, u):
        """meshflow's r^ = P dt u(xi) for a per-vertex flow u (V, 3)."""
        return self.summary(self.tangential(self.dt * self.at_xi(u)))

    def score_displacement(self, t):
        """A tool's 3-D displacement t at xi (N, 3), absolute (the material's): r^ = P (t - m)."""
        return self.summary(self.tangential(t - self.mesh_motion))

    def summary(self, computed):
        truth = self.truth
        epe = np.linalg.norm(computed - truth, axis=1)
        zero = np.linalg.norm(truth, axis=1)
        moved = zero >= MOVING_FRACTION * zero.max() if zero.max() > 0 else np.zeros(len(zero), bool)
        cn = np.linalg.norm(computed, axis=1)
        cosang = (computed * truth).sum(1) / np.maximum(cn * zero, 1e-300)
        direction = np.where(cn > 0, np.degrees(np.arccos(np.clip(cosang, -1, 1))), 90.0)
        direction = np.where(moved, direction, np.nan)
        speed = np.where(moved, cn / np.maximum(zero, 1e-300), np.nan)
        return {
            "points": int(len(epe)),
            "moving": int(moved.sum()),
            "mean_endpoint": float(epe.mean()),
            "median_endpoint": lower_median(epe),
            "zero_mean_endpoint": float(zero.mean()),
            "endpoint_ratio": float(epe.mean() / zero.mean()),
            "median_direction_degrees": lower_median(direction),
            "median_speed_ratio": lower_median(speed),
        }


# ----------------------------------------------------------------------------- images


def fit_sphere(points):
    """Algebraic least squares: |x|^2 = 2 c.x + (r^2 - |c|^2)."""
    A = np.c_[2 * points, np.ones(len(points))]
    sol, *_ = np.linalg.lstsq(A, (points**2).sum(1), rcond=None)
    c = sol[:3]
    return c, float(np.sqrt(sol[3] + c @ c))


class SphereChart:
    """Azimuthal equidistant chart of a sphere about an axis; pixel (row, col) at
    (u, v) = ((col - c0) h, (row - c0) h) um on the sphere of radius R."""

    def __init__(self, centre, radius, axis, half_size):
        self.c, self.R = np.asarray(centre, float), float(radius)
        a = np.asarray(axis, float)
        self.a = a / np.linalg.norm(a)
        helper = np.array([1.0, 0, 0]) if abs(self.a[0]) < 0.9 else np.array([0, 1.0, 0])
        e1 = helper - self.a * (helper @ self.a)
        self.e1 = e1 / np.linalg.norm(e1)
        self.e2 = np.cross(self.a, self.e1)
        self.c0 = float(np.ceil(half_size / PIXEL))
        self.size = int(2 * self.c0 + 1)

    def direction(self, rows, cols):
        u, v = (cols - self.c0) * PIXEL, (rows - self.c0) * PIXEL
        rho = np.hypot(u, v)
        ang = rho / self.R
        s = np.where(rho > 0, np.sin(ang) / np.maximum(rho, 1e-300), 1.0 / self.R)
        return (
            np.cos(ang)[..., None] * self.a
            + (s * u)[..., None] * self.e1
            + (s * v)[..., None] * self.e2
        )

    def to_pixels(self, points):
        w = points - self.c
        w /= np.linalg.norm(w, axis=1)[:, None]
        ang = np.arccos(np.clip(w @ self.a, -1, 1))
        pu, pv = w @ self.e1, w @ self.e2
        norm = np.hypot(pu, pv)
        scale = np.where(norm > 0, self.R * ang / np.maximum(norm, 1e-300), 0.0)
        return np.stack([pv * scale / PIXEL + self.c0, pu * scale / PIXEL + self.c0], 1)  # row, col

    def jacobian(self, points):
        """d(3-D point on the sphere through `points`)/d(row, col), (N, 3, 2), um per pixel."""
        rc = self.to_pixels(points)
        r = np.linalg.norm(points - self.c, axis=1)[:, None]
        J = np.empty((len(points), 3, 2))
        for k in range(2):
            e = np.zeros(2)
            e[k] = 0.5
            plus = self.direction(*(rc + e).T) * r
            minus = self.direction(*(rc - e).T) * r
            J[:, :, k] = plus - minus
        return J


def sample_volume(vol, points):
    """Trilinear samples of vol (k, j, i) at physical points (..., 3) (x, y, z), 0 outside."""
    coords = np.stack([points[..., 2] / VOXEL[2], points[..., 1] / VOXEL[1], points[..., 0] / VOXEL[0]])
    flat = coords.reshape(3, -1)
    inside = np.all((flat >= 0) & (flat <= (np.array(vol.shape) - 1)[:, None]), axis=0)
    out = ndimage.map_coordinates(vol, flat, order=1, mode="constant", cval=0.0)
    out[~inside] = 0.0
    return out.reshape(points.shape[:-1])


def reference_sphere(surface_dir, vertices):
    """The sphere meshflow's surface is a height over (surface.json), else a fitted one."""
    try:
        ref = json.loads((Path(surface_dir) / "surface.json").read_text())["reference"]["Sphere"]
        return np.array(ref["centre"], float), float(ref["radius"])
    except (OSError, KeyError, TypeError, ValueError):
        return fit_sphere(vertices)


def shell_radius(chart, vertices=None):
    """Per chart pixel, the radius the shell is centred on: the sphere's (vertices None), or
    that of the surface through `vertices` along the pixel's ray (linear over the vertices'
    chart positions, nearest beyond them)."""
    if vertices is None:
        return np.full((chart.size, chart.size), chart.R)
    from scipy.interpolate import LinearNDInterpolator, NearestNDInterpolator

    rc = chart.to_pixels(vertices)
    r = np.linalg.norm(vertices - chart.c, axis=1)
    rows, cols = np.mgrid[0 : chart.size, 0 : chart.size].astype(float)
    q = np.stack([rows.ravel(), cols.ravel()], 1)
    out = LinearNDInterpolator(rc, r)(q)
    gap = np.isnan(out)
    out[gap] = NearestNDInterpolator(rc, r)(q[gap])
    return out.reshape(rows.shape)


def pullback(vol, chart, radius):
    """Max over LAYERS samples within +-SHELL of `radius` (per pixel) along each pixel's ray
    of the volume smoothed by SIGMA (meshflow sample's defaults)."""
    smooth = ndimage.gaussian_filter(vol.astype(np.float32), SIGMA / VOXEL[::-1], mode="nearest")
    rows, cols = np.mgrid[0 : chart.size, 0 : chart.size].astype(float)
    d = chart.direction(rows, cols)
    image = np.zeros((chart.size, chart.size), np.float32)
    for s in np.linspace(-SHELL, SHELL, LAYERS):
        image = np.maximum(image, sample_volume(smooth, chart.c + (radius + s)[..., None] * d))
    return image


def normalize_pair(a, b):
    """Both frames on one scale to [0, 1] (the recording is already 8-bit in [0, 1])."""
    hi = max(float(a.max()), float(b.max()), 1e-12)
    return np.clip(a / hi, 0, 1).astype(np.float32), np.clip(b / hi, 0, 1).astype(np.float32)


# ----------------------------------------------------------------------------- the tools
# Each returns a function (rows, cols) -> (N, 2) displacement (drow, dcol) in pixels of the
# flow from frame 0 to frame 1 at frame-0 positions (or, for 3-D, (k, j, i) -> (N, 3)).


def presmooth(img, sigma):
    return ndimage.gaussian_filter(img, sigma) if sigma else img


def dense_sampler(flow):
    """flow (C, ...) in array axis order -> sampler of its components at positions (N, C)."""

    def at(*coords):
        return np.stack([ndimage.map_coordinates(f, np.stack(coords), order=1, mode="nearest") for f in flow], 1)

    return at


def run_farneback(a, b, p):
    a, b = presmooth(a, p.get("presmooth", 0)), presmooth(b, p.get("presmooth", 0))
    a8 = np.round(255 * np.clip(a, 0, 1)).astype(np.uint8)
    b8 = np.round(255 * np.clip(b, 0, 1)).astype(np.uint8)
    flags = cv2.OPTFLOW_FARNEBACK_GAUSSIAN if p.get("gaussian") else 0
    f = cv2.calcOpticalFlowFarneback(
        a8, b8, None, p["pyr_scale"], p["levels"], p["winsize"], p["iterations"], p["poly_n"], p["poly_sigma"], flags
    )
    return dense_sampler(np.stack([f[..., 1], f[..., 0]]))  # (drow, dcol)


def run_tvl1(a, b, p):
    a, b = presmooth(a, p.get("presmooth", 0)), presmooth(b, p.get("presmooth", 0))
    kw = {k: v for k, v in p.items() if k != "presmooth"}
    return dense_sampler(optical_flow_tvl1(a, b, **kw))


def run_ilk(a, b, p):
    a, b = presmooth(a, p.get("presmooth", 0)), presmooth(b, p.get("presmooth", 0))
    kw = {k: v for k, v in p.items() if k != "presmooth"}
    return dense_sampler(optical_flow_ilk(a, b, **kw))


def run_piv(a, b, p):
    """OpenPIV cross-correlation on 8-bit-scaled images (as simple_piv's int images)."""
    a, b = presmooth(a, p.get("presmooth", 0)), presmooth(b, p.get("presmooth", 0))
    a, b = 255.0 * a.astype(np.float64), 255.0 * b.astype(np.float64)
    if p.get("multipass"):
        from openpiv import windef

        settings = windef.PIVSettings()
        settings.windowsizes = tuple(p["multipass"])
        settings.overlap = tuple(w // 2 for w in p["multipass"])
        settings.num_iterations = len(p["multipass"])
        # Windows with no signal (the pullback outside the stack) give NaN vectors, and a NaN
        # left after a pass spreads through windef's image deformation to the whole next
        # pass, whose validation then rejects every vector ("Something happened in the
        # validation", openpiv 0.26). A floor of noise of 0.1 grey level, drawn anew up to
        # 5 times, gets past it.
        for seed in range(5):
            rng = np.random.default_rng(seed)
            try:
                x, y, u, v, _ = windef.simple_multipass(
                    a + 0.1 * rng.random(a.shape), b + 0.1 * rng.random(b.shape), settings
                )
                break
            except ValueError:
                if seed == 4:
                    raise
        # undo its transform_coordinates (y flipped, v negated): back to image rows
        y, v = y[::-1, :], -np.asarray(v, float)
        u = np.asarray(u, float)
    else:
        ws, ov, sa = p["window_size"], p["overlap"], p["search_area_size"]
        u, v, s2n = piv_pyprocess.extended_search_area_piv(
            a, b, window_size=ws, overlap=ov, dt=1.0, search_area_size=sa,
            sig2noise_method=p.get("sig2noise_method", "peak2mean"),
        )
        x, y = piv_pyprocess.get_coordinates(image_size=a.shape, search_area_size=sa, overlap=ov)
        u, v = np.asarray(u, float), np.asarray(v, float)
        validate = p.get("validate", "percentile5")
        if validate == "percentile5":  # simple_piv's default: the 5 % lowest s2n replaced
            flags = ~(s2n > np.percentile(s2n, 5))
        elif validate == "tutorial1":  # tutorial1.py: s2n < 1.2 or beyond +-10 px
            flags = piv_validation.sig2noise_val(s2n, threshold=1.2)
            flags |= piv_validation.global_val(u, v, (-10, 10), (-10, 10))
        else:
            flags = np.zeros(u.shape, bool)
        if flags.any():
            u, v = piv_filters.replace_outliers(u, v, flags, method="localmean", max_iter=10, kernel_size=2)
            u, v = np.asarray(np.ma.filled(u, np.nan), float), np.asarray(np.ma.filled(v, np.nan), float)
    u, v = np.nan_to_num(u), np.nan_to_num(v)
    rows, cols = y[:, 0], x[0, :]
    # openpiv (0.26) returns v along increasing rows before tools.transform_coordinates
    # (checked by self_test): drow = v, dcol = u.
    interps = [
        RegularGridInterpolator((rows, cols), comp, bounds_error=False, fill_value=None)
        for comp in (v, u)
    ]

    def at(r, c):
        q = np.stack([np.clip(r, rows.min(), rows.max()), np.clip(c, cols.min(), cols.max())], 1)
        return np.stack([f(q) for f in interps], 1)

    return at


def run_ilk3d(a, b, p):
    if p.get("presmooth_um"):
        s = p["presmooth_um"] / VOXEL[::-1]
        a, b = ndimage.gaussian_filter(a, s, mode="nearest"), ndimage.gaussian_filter(b, s, mode="nearest")
    kw = {k: v for k, v in p.items() if k != "presmooth_um"}
    return dense_sampler(optical_flow_ilk(a, b, **kw))


RUNNERS = {"farneback": run_farneback, "tvl1": run_tvl1, "ilk": run_ilk, "piv": run_piv, "ilk3d": run_ilk3d}

FARNEBACK = dict(pyr_scale=0.5, levels=3, winsize=15, iterations=3, poly_n=5, poly_sigma=1.2)
DEFAULTS = {
    # OpenCV's tutorial / samples/python/opt_flow.py values (the function has no defaults).
    "farneback": FARNEBACK,
    "tvl1": dict(attachment=15, tightness=0.3, num_warp=5, num_iter=10, tol=1e-4, prefilter=False),
    "ilk": dict(radius=7, num_warp=10, gaussian=False, prefilter=False),
    # openpiv.piv.simple_piv's: window 32, overlap 16, search 32, peak2mean, the 5 % of
    # vectors of lowest signal-to-noise replaced by their neighbours' mean.
    "piv": dict(window_size=32, overlap=16, search_area_size=32),
    "ilk3d": dict(radius=7, num_warp=10, gaussian=False, prefilter=False),
}
SWEEPS = {
    "farneback": [
        dict(winsize=5), dict(winsize=7), dict(winsize=11), dict(winsize=25), dict(winsize=35),
        dict(winsize=51), dict(levels=5), dict(iterations=10), dict(poly_n=7, poly_sigma=1.5),
        dict(gaussian=True), dict(gaussian=True, winsize=25), dict(presmooth=1), dict(presmooth=2),
    ],
    "tvl1": [
        dict(attachment=3), dict(attachment=7), dict(attachment=30), dict(attachment=60),
        dict(tightness=0.1), dict(tightness=0.8), dict(num_warp=10), dict(num_iter=30),
        dict(prefilter=True), dict(presmooth=1), dict(presmooth=2),
        dict(attachment=7, presmooth=2), dict(attachment=3, prefilter=True),
    ],
    "ilk": [
        dict(radius=3), dict(radius=5), dict(radius=10), dict(radius=15), dict(radius=20),
        dict(radius=30), dict(gaussian=True), dict(gaussian=True, radius=15),
        dict(prefilter=True), dict(presmooth=1), dict(presmooth=2), dict(radius=15, presmooth=2),
    ],
    "piv": [
        dict(window_size=16, overlap=8, search_area_size=16),
        dict(window_size=16, overlap=12, search_area_size=16),
        dict(window_size=24, overlap=12, search_area_size=24),
        dict(window_size=24, overlap=18, search_area_size=24),
        dict(window_size=32, overlap=24, search_area_size=32),
        dict(window_size=48, overlap=24, search_area_size=48),
        dict(window_size=64, overlap=32, search_area_size=64),
        dict(window_size=24, overlap=12, search_area_size=32),
        # tutorial1.py: extended search 64, peak2peak, s2n 1.2 and +-10 px validation
        dict(search_area_size=64, sig2noise_method="peak2peak", validate="tutorial1"),
        dict(validate="none"),
        dict(multipass=(64, 32, 16)),
        dict(presmooth=1), dict(presmooth=2),
    ],
    # 3-D ILK costs about 3 min a run (44 x 512 x 512): three settings, with --sweep-3d only.
    "ilk3d": [dict(radius=15), dict(gaussian=True), dict(presmooth_um=SIGMA)],
}
IMAGES = {"farneback": ("proj", "pull"), "tvl1": ("proj", "pull"), "ilk": ("proj", "pull"),
          "piv": ("proj", "pull"), "ilk3d": ("vol",)}


def setting_label(change):
    return "defaults" if not change else ",".join(f"{k}={v}" for k, v in change.items())


def self_test(methods):
    """Each tool's sign and axis convention on a blob image shifted by (+1.5 rows, +2.5 cols)."""
    rng = np.random.default_rng(1)
    img = ndimage.gaussian_filter(rng.random((160, 160)), 3)
    img = (img - img.min()) / np.ptp(img)
    moved = ndimage.shift(img, (1.5, 2.5), order=3, mode="nearest")
    out = {}
    for m in methods:
        if m == "ilk3d":
            vol = ndimage.gaussian_filter(rng.random((24, 64, 64)), 2)
            vol = (vol - vol.min()) / np.ptp(vol)
            sh = ndimage.shift(vol, (0.5, 1.5, 2.5), order=3, mode="nearest")
            at = RUNNERS[m](vol.astype(np.float32), sh.astype(np.float32), DEFAULTS[m])
            got = at(np.full(1, 12.0), np.full(1, 32.0), np.full(1, 32.0))[0]
            want = np.array([0.5, 1.5, 2.5])
        else:
            # PIV without extended search is biased towards 0 in this small test: search 64
            params = dict(DEFAULTS[m], search_area_size=64) if m == "piv" else DEFAULTS[m]
            at = RUNNERS[m](img.astype(np.float32), moved.astype(np.float32), params)
            got = at(np.full(1, 80.0), np.full(1, 80.0))[0]
            want = np.array([1.5, 2.5])
        ok = np.allclose(got, want, atol=0.5)
        out[m] = (ok, got)
        if not ok:
            raise SystemExit(f"self-test: {m} gives {got} for a shift of {want}: convention changed?")
    return out


# ----------------------------------------------------------------------------- per pair


def pattern(p, pair):
    return str(p).replace("{pair}", pair)


def prepare_pair(args, pair, cache):
    """Images (cached), the scorer, and the lift matrices: displacement = L @ flow at xi."""
    scorer = Scorer(pattern(args.surface, pair), pattern(args.tracks, pair))
    vdir = Path(args.data) / pair / "volumes"
    files = sorted(vdir.glob("*.npy"), key=natural_key)
    if len(files) != 2:
        raise SystemExit(f"{vdir}: {len(files)} volumes, expected 2")
    vols = [np.load(f).astype(np.float32) for f in files]
    xi, n = scorer.xi, scorer.normal
    lifts = {}
    positions = {}
    # projection
    np.save(cache / f"proj_{pair}.npy", np.stack([v.max(axis=0) for v in vols]))
    positions["proj"] = np.stack([xi[:, 1] / PIXEL, xi[:, 0] / PIXEL])  # row, col
    L = np.zeros((len(xi), 3, 2))
    L[:, 0, 1] = L[:, 1, 0] = PIXEL  # x <- dcol, y <- drow
    if args.lift == "ray":
        nz = np.where(np.abs(n[:, 2]) < 0.1, np.copysign(0.1, n[:, 2]), n[:, 2])
        L[:, 2, 1] = -PIXEL * n[:, 0] / nz
        L[:, 2, 0] = -PIXEL * n[:, 1] / nz
    else:
        L = np.einsum("nij,njk->nik", scorer.P, L)
    lifts["proj"] = L
    # spherical pullback: the reference sphere of the meshflow surface (surface.json), else a
    # sphere fitted to frame 0's vertices; chart about the cells' mean direction
    c, R = reference_sphere(pattern(args.surface, pair), scorer.X[0])
    w = scorer.p0 - c
    w /= np.linalg.norm(w, axis=1)[:, None]
    axis = w.mean(0)
    axis /= np.linalg.norm(axis)
    reach = R * np.arccos(np.clip(w @ axis, -1, 1)).max() + 50.0
    chart = SphereChart(c, R, axis, reach)
    guide = {"surface": list(scorer.X), "surface0": [scorer.X[0]] * 2, "sphere": [None, None]}[args.pullback]
    shells = [shell_radius(chart, X) for X in guide]
    np.save(cache / f"pull_{pair}.npy", np.stack([pullback(v, chart, r) for v, r in zip(vols, shells)]))
    positions["pull"] = chart.to_pixels(xi).T
    J = chart.jacobian(xi)
    radial = (xi - c) / np.linalg.norm(xi - c, axis=1)[:, None]
    # lift along the radius into the tangent plane: t = d - radial (n.d)/(n.radial)
    ray = np.eye(3)[None] - radial[:, :, None] * n[:, None, :] / (n * radial).sum(1)[:, None, None]
    lifts["pull"] = np.einsum("nij,njk->nik", ray, J)
    # volume: flow (dk, dj, di) voxels -> (x, y, z) um
    positions["vol"] = np.stack([xi[:, 2] / VOXEL[2], xi[:, 1] / VOXEL[1], xi[:, 0] / VOXEL[0]])
    Lv = np.zeros((len(xi), 3, 3))
    Lv[:, 0, 2], Lv[:, 1, 1], Lv[:, 2, 0] = VOXEL[0], VOXEL[1], VOXEL[2]
    lifts["vol"] = Lv
    # What a perfect tool on each image would score: the cell centres' own image motion
    # (their xy motion; their chart motion), lifted like a tool's flow. The projection's
    # floor is the centres' motion along z that its lift cannot see.
    d = scorer.p1 - scorer.p0
    oracle = {
        "proj": np.einsum("nij,nj->ni", lifts["proj"], np.c_[d[:, 1], d[:, 0]] / PIXEL),
        "pull": np.einsum("nij,nj->ni", lifts["pull"], chart.to_pixels(scorer.p1) - chart.to_pixels(scorer.p0)),
    }
    height = np.linalg.norm(scorer.X[0] - c, axis=1) - R
    info = {
        "perfect_tool_endpoint_ratio": {k: scorer.score_displacement(t)["endpoint_ratio"] for k, t in oracle.items()},
        "sphere_centre": c.tolist(), "sphere_radius": R, "chart_axis": axis.tolist(),
        "chart_pixels": chart.size, "cells": len(xi),
        "largest_cell_angle_degrees": float(np.degrees((reach - 50.0) / R)),
        "surface_minus_sphere_um_p5_p95": np.percentile(height, [5, 95]).tolist(),
        "cells_outside_sphere_shell": int((np.abs(np.linalg.norm(xi - c, axis=1) - R) > SHELL).sum()),
        "mean_tangential_mesh_motion_um": float(np.linalg.norm(scorer.tangential(scorer.mesh_motion), axis=1).mean()),
        "dt": scorer.dt,
    }
    return scorer, positions, lifts, [str(f) for f in files], info


PREP = {}  # pair -> scorer, positions, lifts, files (filled before the workers fork)


def cached_flow(pair, method, image, change, params, a, b, prep, cache):
    """The tool's flow at the evaluation positions; 3-D ILK (minutes a run) is cached in
    CACHE/ilk3d_*.npy, keyed by the setting, the positions and the volume files."""
    pos = prep["positions"][image]
    run = lambda: RUNNERS[method](a, b, params)(*pos)  # noqa: E731
    if method != "ilk3d":
        return _quietly(run)
    import hashlib

    h = hashlib.sha1(np.ascontiguousarray(pos).tobytes())
    h.update(json.dumps(params, sort_keys=True, default=str).encode())
    for f in prep["files"]:
        st = os.stat(f)
        h.update(f"{f}:{st.st_size}:{st.st_mtime_ns}".encode())
    path = Path(cache) / f"ilk3d_{pair}_{h.hexdigest()[:16]}.npy"
    if path.exists():
        return np.load(path)
    d = _quietly(run)
    np.save(path, d)
    return d


def _quietly(f):
    """openpiv prints to stdout ("Found 0 bad peak(s)"); keep the table clean."""
    import contextlib
    import io

    with contextlib.redirect_stdout(io.StringIO()):
        return f()


def work_item(job):
    """One tool on one image of one pair, over its settings."""
    pair, method, image, settings, cache = job
    prep = PREP[pair]
    scorer = prep["scorer"]
    if image == "vol":
        a, b = normalize_pair(*[np.load(f).astype(np.float32) for f in prep["files"]])
    else:
        a, b = normalize_pair(*np.load(Path(cache) / f"{image}_{pair}.npy"))
    out = []
    for change in settings:
        params = dict(DEFAULTS[method], **change)
        t0 = time.time()
        try:
            d = cached_flow(pair, method, image, change, params, a, b, prep, cache)
            disp = np.einsum("nij,nj->ni", prep["lifts"][image], d)
            s = scorer.score_displacement(disp)
        except Exception as e:  # a setting a tool refuses is reported, not fatal
            s = {"error": f"{type(e).__name__}: {e}"}
        s["seconds"] = time.time() - t0
        out.append((pair, method, image, setting_label(change), s))
    return out


def meshflow_score(scorer_cache, flow_dir, surface_dir, tracks):
    flow_dir = Path(flow_dir)
    if surface_dir is None:
        run = json.loads((flow_dir / "meshflow_run.json").read_text())
        pos = [i["path"] for i in run.get("inputs", []) if i["path"].endswith("positions.npy")]
        if not pos:
            raise SystemExit(f"{flow_dir}/meshflow_run.json names no positions.npy: give NAME=FLOW@SURFACE")
        first = Path(pos[0])
        if not first.is_absolute():
            first = Path(run.get("directory", flow_dir.parent)) / first
        surface_dir = str(first.parent)
    key = (str(Path(surface_dir).resolve()), str(Path(tracks).resolve()))
    if key not in scorer_cache:
        scorer_cache[key] = Scorer(surface_dir, tracks)
    scorer = scorer_cache[key]
    flow = np.load(flow_dir / "flow.npy")
    if flow.shape[1] != scorer.X.shape[1]:
        raise SystemExit(f"{flow_dir}/flow.npy has {flow.shape[1]} vertices, {surface_dir} {scorer.X.shape[1]}")
    s = scorer.score_velocity(flow[0])
    printed = None
    summary = flow_dir / "summary.json"
    if summary.exists():
        gt = json.loads(summary.read_text()).get("ground_truth_tracks")
        if gt:
            printed = {k: gt[k] for k in ("endpoint_ratio", "median_speed_ratio", "mean_endpoint", "zero_mean_endpoint")}
    s["meshflow_printed"] = printed
    s["surface"] = surface_dir
    return s


# ----------------------------------------------------------------------------- main


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("data", help="the converter's output folder (with PAIR/volumes/)")
    ap.add_argument("--work", default=".", help="folder of the meshflow runs (default .)")
    ap.add_argument("--pairs", default=",".join(PAIRS))
    ap.add_argument("--surface", default=None, help="surface folder pattern (default WORK/surf_{pair})")
    ap.add_argument("--tracks", default=None, help="tracks pattern (default WORK/tracks_{pair}.npy)")
    ap.add_argument("--flow", default=None, help="meshflow flow folder pattern (default WORK/flow_{pair})")
    ap.add_argument("--meshflow-flow", action="append", default=[], metavar="NAME=PATTERN[@SURFACE]")
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--sweep", action="store_true", help="also sweep about a dozen settings per tool")
    g.add_argument("--defaults-only", action="store_true", help="each tool's defaults only (the default)")
    ap.add_argument("--methods", default="farneback,tvl1,ilk,piv,ilk3d")
    ap.add_argument("--no-3d", action="store_true", help="skip 3-D ILK on the volumes")
    ap.add_argument("--sweep-3d", action="store_true",
                    help="with --sweep, sweep 3-D ILK too (3 settings, about 3 min each a pair)")
    ap.add_argument("--lift", choices=["ray", "tangential"], default="ray",
                    help="projection flow to the surface: along the z ray (default) or P(dx,dy,0)")
    ap.add_argument("--pullback", choices=["surface", "surface0", "sphere"], default="surface",
                    help="pullback shell about each frame's meshflow surface along each ray "
                         "(default, as meshflow sample), about frame 0's for both, or about the sphere")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default=None, help="results folder (default WORK/field_tools)")
    args = ap.parse_args()
    work = Path(args.work)
    args.surface = args.surface or str(work / "surf_{pair}")
    args.tracks = args.tracks or str(work / "tracks_{pair}.npy")
    args.flow = args.flow or str(work / "flow_{pair}")
    out = Path(args.out or work / "field_tools")
    cache = out / "cache"
    cache.mkdir(parents=True, exist_ok=True)
    pairs = [p for p in args.pairs.split(",") if p]
    t_start = time.time()

    methods = [m for m in args.methods.split(",") if m]
    if args.no_3d:
        methods = [m for m in methods if m != "ilk3d"]
    for m in list(methods):
        if m not in RUNNERS:
            raise SystemExit(f"unknown method {m}; known: {', '.join(RUNNERS)}")
        if m in MISSING:
            print(f"skipping {m}: {MISSING[m]}", file=sys.stderr)
            methods.remove(m)
    checked = self_test(methods)
    print("conventions checked (shift +1.5 rows, +2.5 cols[, +0.5 slices]):",
          ", ".join(f"{m} {np.round(g, 2).tolist()}" for m, (ok, g) in checked.items()), file=sys.stderr)

    flows = {"meshflow": (args.flow, None)}
    for spec in args.meshflow_flow:
        name, _, pat = spec.partition("=")
        if not name or not pat:
            raise SystemExit(f"--meshflow-flow {spec!r}: expected NAME=PATTERN[@SURFACEPATTERN]")
        fpat, _, spat = pat.partition("@")
        flows[f"meshflow:{name}" if name != "meshflow" else name] = (fpat, spat or None)

    # --- per pair: images, scorer, lifts; meshflow runs scored
    results = {"pairs": pairs, "scores": [], "info": {}, "settings": {}, "meshflow": {}}
    scorer_cache = {}
    jobs = []
    for pair in pairs:
        t0 = time.time()
        scorer, positions, lifts, files, info = prepare_pair(args, pair, cache)
        scorer_cache[(str(Path(pattern(args.surface, pair)).resolve()), str(Path(pattern(args.tracks, pair)).resolve()))] = scorer
        info["prepare_seconds"] = time.time() - t0
        results["info"][pair] = info
        PREP[pair] = {"scorer": scorer, "positions": positions, "lifts": lifts, "files": files}
        perfect = info["perfect_tool_endpoint_ratio"]
        print(f"{pair}: {info['cells']} cells, sphere R {info['sphere_radius']:.1f} um, chart {info['chart_pixels']} px, "
              f"prepared in {info['prepare_seconds']:.1f} s; a perfect tool would score "
              f"{perfect['proj']:.3f} on the projection, {perfect['pull']:.3f} on the pullback", file=sys.stderr)
        for name, (fpat, spat) in flows.items():
            fdir = pattern(fpat, pair)
            if not Path(fdir, "flow.npy").exists():
                print(f"  {name}: {fdir}/flow.npy missing, skipped", file=sys.stderr)
                continue
            s = meshflow_score(scorer_cache, fdir, pattern(spat, pair) if spat else None, pattern(args.tracks, pair))
            results["meshflow"].setdefault(name, {})[pair] = s
            pr = s["meshflow_printed"]
            check = (f" (meshflow printed {pr['endpoint_ratio']:.4f}, speed {pr['median_speed_ratio']:.4f})" if pr else "")
            print(f"  {name}: ratio {s['endpoint_ratio']:.4f}, speed {s['median_speed_ratio']:.4f}{check}", file=sys.stderr)
        for m in methods:
            sweep = args.sweep and (m != "ilk3d" or args.sweep_3d)
            settings = [{}] + (SWEEPS[m] if sweep else [])
            for image in IMAGES[m]:
                jobs.append((pair, m, image, settings, str(cache)))
                results["settings"][m] = [setting_label(c) for c in settings]
    # the slow 3-D jobs first, so that two workers finish together
    jobs.sort(key=lambda j: (j[1] != "ilk3d", j[1] != "tvl1"))
    t0 = time.time()
    if args.jobs > 1 and len(jobs) > 1:
        from multiprocessing import get_context

        with get_context("fork").Pool(args.jobs) as pool:
            for batch in pool.imap_unordered(work_item, jobs):
                report(batch, results)
    else:
        for job in jobs:
            report(work_item(job), results)
    results["tools_seconds"] = time.time() - t0
    results["total_seconds"] = time.time() - t_start
    results["lift"] = args.lift
    results["pullback"] = args.pullback
    write_tables(results, out)


def report(batch, results):
    for pair, m, image, label, s in batch:
        results["scores"].append({"pair": pair, "method": m, "image": image, "setting": label, **s})
    pair, m, image = batch[0][:3]
    d = [s for p_, m_, i_, l, s in batch if l == "defaults"][0]
    secs = sum(s["seconds"] for *_, s in batch)
    print(f"  {pair} {m} on {image}: defaults {d.get('endpoint_ratio', float('nan')):.3f} "
          f"({len(batch)} settings, {secs:.0f} s)", file=sys.stderr)


def write_tables(results, out):
    pairs = results["pairs"]
    rows = results["scores"]
    cols = []  # (title, {pair: summary}, setting)
    for m in ["farneback", "tvl1", "ilk", "piv", "ilk3d"]:
        for image in IMAGES[m]:
            sel = [r for r in rows if r["method"] == m and r["image"] == image and "endpoint_ratio" in r]
            if not sel:
                continue
            by_setting = {}
            for r in sel:
                by_setting.setdefault(r["setting"], {})[r["pair"]] = r
            complete = {k: v for k, v in by_setting.items() if all(p in v for p in pairs)}
            if "defaults" in complete:
                cols.append((f"{m} {image} defaults", complete["defaults"], "defaults"))
            if len(complete) > 1:
                best = min(complete, key=lambda k: np.mean([complete[k][p]["endpoint_ratio"] for p in pairs]))
                cols.append((f"{m} {image} tuned", complete[best], best))
    for name, per_pair in results["meshflow"].items():
        if all(p in per_pair for p in pairs):
            cols.append((name, per_pair, "as run"))
    table = {"pairs": pairs, "columns": []}
    lines = []
    for key, title in (("endpoint_ratio", "endpoint error ÷ zero flow's (mean over cells)"),
                       ("median_speed_ratio", "median speed ratio |r^|/|r|")):
        lines.append(f"\n{title}\n")
        lines.append("| column | setting | " + " | ".join(pairs) + " | mean |")
        lines.append("|---|---|" + "---|" * (len(pairs) + 1))
        for t, per_pair, setting in cols:
            vals = [per_pair[p][key] for p in pairs]
            lines.append(f"| {t} | {setting} | " + " | ".join(f"{v:.3f}" for v in vals) + f" | {np.mean(vals):.3f} |")
    for t, per_pair, setting in cols:
        table["columns"].append({
            "column": t, "setting": setting,
            "endpoint_ratio": {p: per_pair[p]["endpoint_ratio"] for p in pairs},
            "median_speed_ratio": {p: per_pair[p]["median_speed_ratio"] for p in pairs},
            "median_direction_degrees": {p: per_pair[p]["median_direction_degrees"] for p in pairs},
            "mean_endpoint_ratio": float(np.mean([per_pair[p]["endpoint_ratio"] for p in pairs])),
        })
    text = "\n".join(lines) + "\n"
    text += f"\ntools {results['tools_seconds']:.0f} s, total {results['total_seconds']:.0f} s\n"
    print(text)
    (out / "table.md").write_text(text)
    (out / "table.json").write_text(json.dumps(table, indent=1))
    (out / "results.json").write_text(json.dumps(results, indent=1, default=str))
    print(f"wrote {out}/table.md, table.json, results.json", file=sys.stderr)


if __name__ == "__main__":
    main()
