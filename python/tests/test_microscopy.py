"""Microscopy workflows: tracks from point clouds, a flow scored at tracked points (the same
numbers as the CLI's summary.json), a surface fitted through points, a volume read onto it,
and the whole chain from points and volumes to a scored flow."""

import json

import numpy as np
import pytest

import meshflow
from conftest import SAMPLE, run

OMEGA_PER_FRAME = 0.05  # the shipped sample's texture turns 0.05 rad per frame about z


def turning_tracks(n_frames: int, n_points: int = 80) -> np.ndarray:
    """Material points of the sample's texture: a Fibonacci lattice turned about z."""
    i = np.arange(n_points) + 0.5
    z = 0.9 - 1.8 * i / n_points
    phi = np.pi * (3 - np.sqrt(5)) * i
    r = np.sqrt(1 - z**2)
    frames = []
    for k in range(n_frames):
        angle = phi + OMEGA_PER_FRAME * k
        frames.append(np.stack([r * np.cos(angle), r * np.sin(angle), z], axis=1))
    return np.array(frames)


def test_match_tracks_recovers_a_shuffled_cloud():
    tracks = turning_tracks(3)
    shuffled = [tracks[0], tracks[1][::-1], tracks[2][np.argsort(tracks[2][:, 0])]]
    matched = meshflow.match_tracks(shuffled)
    assert matched.shape == tracks.shape
    assert np.array_equal(matched, tracks)
    with pytest.raises(ValueError, match="positive number"):
        meshflow.match_tracks(shuffled, max_distance=0)


def test_score_tracks_matches_the_cli(sample, cli, tmp_path):
    tracks = turning_tracks(len(sample.times))
    np.save(tmp_path / "tracks.npy", tracks)
    flow = sample.compute_flow()
    scores = meshflow.score_tracks(flow, tracks)
    assert scores["per_point"]["endpoint"].shape == (80 * (len(sample.times) - 1),)
    # The default flow is 27 % slow on this coarse sphere (README), yet well inside the
    # zero flow's error.
    assert scores["endpoint_ratio"] < 0.5
    assert scores["median_direction_degrees"] < 10
    assert 0.6 < scores["median_speed_ratio"] < 1.0
    run(cli, "solve", SAMPLE, "--out", tmp_path / "run", "--format", "npy",
        "--ground-truth-tracks", tmp_path / "tracks.npy")
    cli_scores = json.loads((tmp_path / "run" / "summary.json").read_text())["ground_truth_tracks"]
    for key in ("mean_endpoint", "zero_mean_endpoint", "median_speed_ratio", "points"):
        assert cli_scores[key] == pytest.approx(scores[key], rel=1e-12), key
    with pytest.raises(ValueError, match="frames, the sequence has"):
        meshflow.score_tracks(flow, tracks[:2])


# ---------------------------------------------------------------------------------------------
# fit_surface, sample_volume.

CENTRE = np.array([10.0, -5.0, 3.0])


def cap_points(n: int, radius: float, centre, half_angle_degrees: float, axis=(0, 0, 1)) -> np.ndarray:
    """A Fibonacci lattice of ``n`` points over the cap of directions within
    ``half_angle_degrees`` of ``axis`` on a sphere (180: the whole sphere)."""
    i = np.arange(n) + 0.5
    cos_theta = 1 - (1 - np.cos(np.radians(half_angle_degrees))) * i / n
    phi = np.pi * (3 - np.sqrt(5)) * i
    r = np.sqrt(1 - cos_theta**2)
    d = np.stack([r * np.cos(phi), r * np.sin(phi), cos_theta], axis=1)
    # The rotation taking z to `axis` (Rodrigues), for a cap that is not axis-aligned.
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    v, c = np.cross([0, 0, 1], a), a[2]
    if np.linalg.norm(v) > 1e-12:
        k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
        d = d @ (np.eye(3) + k + k @ k / (1 + c)).T
    return np.asarray(centre) + radius * d


def test_fit_surface_through_a_sphere_cap():
    axis = np.array([1.0, 1.0, 1.0]) / np.sqrt(3)
    frames = [cap_points(300, 50, CENTRE, 60, axis), cap_points(260, 52, CENTRE, 60, axis)]
    surface = meshflow.fit_surface(frames, vertices=3000)
    positions, faces = surface["positions"], surface["faces"]
    assert positions.dtype == np.float64 and faces.dtype == np.int64
    assert positions.shape[0] == 2 and positions.shape[2] == 3
    assert 1500 < positions.shape[1] < 6000
    assert faces.shape[1] == 3 and faces.min() == 0 and faces.max() == positions.shape[1] - 1
    for frame, radius in zip(positions, (50, 52)):
        distance = np.linalg.norm(frame - CENTRE, axis=1)
        assert np.abs(distance - radius).max() < 0.01 * radius
    reference = surface["reference"]
    assert reference["kind"] == "sphere"
    assert np.allclose(reference["centre"], CENTRE, atol=1e-6)
    assert reference["radius"] == pytest.approx(50, rel=1e-9)
    assert np.dot(reference["axis"], axis) > np.cos(np.radians(1))
    # The points' widest angle (just under 60°) plus one mean point spacing (≈ 6°).
    assert 60 < reference["cap_degrees"] < 70
    assert [f["points"] for f in surface["frames"]] == [300, 260]
    assert all(f["dropped"] == 0 and f["max_residual"] < 1e-6 for f in surface["frames"])
    assert surface["mean_point_spacing"] == pytest.approx(np.sqrt(np.pi * 50**2 / 280), rel=0.2)
    assert surface["lambda"] == pytest.approx(surface["mean_point_spacing"] ** 2)
    # Faces turn counter-clockwise seen from outside: normals away from the centre.
    x = positions[0]
    normals = np.cross(x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]])
    assert (np.einsum("ij,ij->i", normals, x[faces].mean(axis=1) - CENTRE) > 0).all()


def test_fit_surface_takes_tracks_with_nan_rows_and_a_graph():
    tracks = np.stack([cap_points(200, 50, CENTRE, 180), cap_points(200, 50.5, CENTRE, 180)])
    tracks[1, :7] = np.nan       # untracked in frame 1
    surface = meshflow.fit_surface(tracks, whole_sphere=True, edge_length=5.0)
    assert [f["points"] for f in surface["frames"]] == [200, 193]
    partly = tracks.copy()
    partly[0, 9, 2] = np.nan     # a point with one NaN coordinate is broken data, not untracked
    with pytest.raises(ValueError, match="frame 0, point 9 is not finite"):
        meshflow.fit_surface(partly, whole_sphere=True, edge_length=5.0)
    assert surface["reference"]["cap_degrees"] is None
    assert surface["positions"].shape[1] == 2562  # the icosphere of mean edge ≤ 5 on R = 50
    # z = h(x, y) through a tilted plane, raised by 1 in frame 1: the rectangle holds the
    # points, the heights follow the plane among them (the spline's natural boundary bends
    # it a little towards the rim), and a constant lift is lifted exactly.
    xy = np.random.default_rng(3).uniform(0, 20, size=(150, 2))
    plane = np.column_stack([xy, 0.1 * xy[:, 0] - 0.2 * xy[:, 1] + 4])
    graph = meshflow.fit_surface([plane, plane + [0, 0, 1]], "graph", vertices=800)
    assert graph["reference"]["kind"] == "plane"
    assert np.all(np.array(graph["reference"]["min"]) < xy.min(axis=0))
    assert np.all(np.array(graph["reference"]["max"]) > xy.max(axis=0))
    positions = graph["positions"]
    assert 600 < positions.shape[1] < 1000
    assert np.abs(positions[1] - positions[0] - [0, 0, 1]).max() < 1e-9
    among = ((positions[0, :, :2] > 2) & (positions[0, :, :2] < 18)).all(axis=1)
    plane_z = 0.1 * positions[0, among, 0] - 0.2 * positions[0, among, 1] + 4
    assert np.abs(positions[0, among, 2] - plane_z).max() < 0.1
    assert all(f["max_residual"] < 0.3 for f in graph["frames"])


def test_fit_surface_errors():
    points = cap_points(100, 50, CENTRE, 60)
    with pytest.raises(ValueError, match="frame 0 has 3 points; a surface needs at least 4"):
        meshflow.fit_surface([points[:3], points])
    with pytest.raises(ValueError, match="frame 1 has 2 points; a surface needs at least 3"):
        meshflow.fit_surface([points, points[:2]])
    with pytest.raises(ValueError, match="one of vertices and edge_length, not both"):
        meshflow.fit_surface([points], vertices=1000, edge_length=2.0)
    bad = points.copy()
    bad[17, 1] = np.inf
    with pytest.raises(ValueError, match="frame 1, point 17 is not finite"):
        meshflow.fit_surface([points, bad])
    with pytest.raises(ValueError, match="lie on a plane"):
        meshflow.fit_surface([points * [1, 1, 0]])
    with pytest.raises(ValueError, match="expected sphere-like or graph"):
        meshflow.fit_surface([points], "cylinder")
    with pytest.raises(ValueError, match="whole_sphere applies to"):
        meshflow.fit_surface([points], "graph", whole_sphere=True)
    with pytest.raises(ValueError, match="the smoothing must be a positive number"):
        meshflow.fit_surface([points], smoothing=-1)
    with pytest.raises(ValueError, match="vertices must be a whole number"):
        meshflow.fit_surface([points], vertices=-5)
    with pytest.raises(ValueError, match=r"points\[0\] has shape \(100, 2\)"):
        meshflow.fit_surface([points[:, :2]])
    with pytest.raises(ValueError, match="no frames"):
        meshflow.fit_surface([])


VOXEL = (1.0, 1.5, 3.0)
ORIGIN = np.array([-5.0, 2.0, 1.0])
GRADIENT = np.array([0.01, 0.02, 0.03])


def linear_volume(shape=(20, 40, 40)) -> np.ndarray:
    """v(x, y, z) = 0.01 x + 0.02 y + 0.03 z at the voxel centres, (z, y, x) order."""
    k, j, i = np.meshgrid(*(np.arange(n) for n in shape), indexing="ij")
    x, y, z = ORIGIN[0] + i * VOXEL[0], ORIGIN[1] + j * VOXEL[1], ORIGIN[2] + k * VOXEL[2]
    return GRADIENT[0] * x + GRADIENT[1] * y + GRADIENT[2] * z


def linear(points: np.ndarray) -> np.ndarray:
    return points @ GRADIENT


def vertex_normals(x: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The corner-angle-weighted mean of the faces' unit normals (the library's)."""
    corners = x[faces]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    sums = np.zeros_like(x)
    for c in range(3):
        a = corners[:, (c + 1) % 3] - corners[:, c]
        b = corners[:, (c + 2) % 3] - corners[:, c]
        angle = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))
        np.add.at(sums, faces[:, c], angle[:, None] * normal)
    return sums / np.linalg.norm(sums, axis=1, keepdims=True)


@pytest.fixture(scope="module")
def ball():
    """A whole sphere of radius 12 inside the linear volume's box (x ∈ [−5, 34], y ∈ [2,
    60.5], z ∈ [1, 58])."""
    centre = np.array([14.5, 31.0, 29.0])
    surface = meshflow.fit_surface([cap_points(200, 12, centre, 180)], whole_sphere=True,
                                   vertices=600)
    return surface["positions"][0], surface["faces"], centre


def test_sample_volume_reads_a_linear_volume_exactly(ball):
    x, faces, centre = ball
    positions = np.stack([x, x + [2.0, 3.0, -1.0]])
    volume = linear_volume()
    volumes = np.stack([volume, volume])          # float64, stored as float32
    sampled = meshflow.sample_volume(volumes, positions, faces, VOXEL, origin=ORIGIN,
                                     smoothing=0, shell=(3.0, 3.0), layers=7, reduce="mean")
    assert sampled["values"].shape == (2, len(x)) and sampled["values"].dtype == np.float64
    assert sampled["outside"] == [0, 0]
    assert sampled["shell"] == (3.0, 3.0, 7)
    assert sampled["smoothing"] == 0.0
    # The mean over a shell symmetric about the surface of a linear function is its value at
    # the surface; trilinear interpolation is exact for it (up to float32 storage).
    assert np.abs(sampled["values"] - linear(positions)).max() < 1e-5
    # The innermost layer is 3 inside along the outward normal, the middle one on the surface.
    normals = vertex_normals(x, faces)
    assert (np.einsum("ij,ij->i", normals, x - centre) > 0.99 * 12).all()
    innermost = meshflow.sample_volume([volume], x[None], faces, VOXEL, origin=ORIGIN,
                                       smoothing=0, shell=(3.0, 3.0), layers=7,
                                       reduce="layer:0")["values"][0]
    assert np.abs(innermost - linear(x - 3.0 * normals)).max() < 1e-5
    middle = meshflow.sample_volume([volume], x[None], faces, VOXEL, origin=ORIGIN,
                                    smoothing=0, shell=(3.0, 3.0), layers=7,
                                    reduce="layer:3")["values"][0]
    assert np.abs(middle - linear(x)).max() < 1e-5
    # The maximum of a linear function over [−a, a] along n is at an end: v + a|∇v · n|.
    brightest = meshflow.sample_volume([volume], x[None], faces, VOXEL, origin=ORIGIN,
                                       smoothing=0, shell=(3.0, 3.0), layers=7)["values"][0]
    assert np.abs(brightest - (linear(x) + 3.0 * np.abs(normals @ GRADIENT))).max() < 1e-5


def test_sample_volume_counts_vertices_outside(ball):
    x, faces, _ = ball
    shifted = x + [12.0, 0.0, 0.0]                # x up to 38.5, beyond the box's 34
    volume = linear_volume().astype(np.float32)
    sampled = meshflow.sample_volume([volume, volume], np.stack([x, shifted]), faces, VOXEL,
                                     origin=ORIGIN, smoothing=0, shell=(0, 0), layers=1)
    box_max = ORIGIN + (np.array(volume.shape[::-1]) - 1) * VOXEL
    out = ~((shifted >= ORIGIN) & (shifted <= box_max)).all(axis=1)
    assert 20 < out.sum() < len(x) // 2
    assert sampled["outside"] == [0, int(out.sum())]
    values = sampled["values"][1]
    assert (values[out] == 0).all()
    assert np.abs(values[~out] - linear(shifted[~out])).max() < 1e-5
    assert sampled["no_data"].dtype == np.bool_
    assert not sampled["no_data"][0].any() and (sampled["no_data"][1] == out).all()


def test_sample_volume_refuses_a_surface_mostly_outside(ball):
    """A voxel size in mm for positions in µm: refused, naming the sizes, unless allowed."""
    x, faces, _ = ball
    volume = linear_volume().astype(np.float32)
    n = len(x)
    millimetres = np.array(VOXEL) / 1000
    with pytest.raises(ValueError, match=rf"frame 0: {n} of {n} vertices \(100 %\) lie outside"
                                         r".*about 1000 times larger.*allow_outside"):
        meshflow.sample_volume([volume], x[None], faces, millimetres, origin=ORIGIN / 1000)
    allowed = meshflow.sample_volume([volume], x[None], faces, millimetres,
                                     origin=ORIGIN / 1000, allow_outside=True)
    assert allowed["no_data"].all() and (allowed["values"] == 0).all()


def test_sample_volume_defaults_dtypes_and_errors(ball):
    x, faces, _ = ball
    volume = linear_volume()
    default = meshflow.sample_volume([volume], x[None], faces, VOXEL, origin=ORIGIN)
    assert default["smoothing"] == 2.0                 # two of the smallest voxel sides
    assert default["shell"] == (6.0, 6.0, 9)           # two of the largest each way, 9 layers
    assert default["outside"] == [0]
    assert meshflow.sample_volume([volume], x[None], faces, VOXEL, origin=ORIGIN,
                                  layers=3)["shell"] == (6.0, 6.0, 3)
    # Integer volumes are read as their values; any memory order.
    counts = np.round(volume * 100).astype(np.uint16)
    as_int = meshflow.sample_volume([counts], x[None], faces, VOXEL, origin=ORIGIN, smoothing=0)
    as_float = meshflow.sample_volume([np.asfortranarray(counts.astype(np.float64))], x[None],
                                      faces, VOXEL, origin=ORIGIN, smoothing=0)
    assert np.array_equal(as_int["values"], as_float["values"])

    def sample(volumes=(volume,), positions=x[None], **options):
        options = {"origin": ORIGIN, "smoothing": 0, **options}
        return meshflow.sample_volume(list(volumes), positions, faces,
                                      options.pop("voxel_size", VOXEL), **options)

    broken = volume.copy()
    broken[3, 4, 5] = np.nan
    with pytest.raises(ValueError, match=r"volumes\[1\]: voxel \(z 3, y 4, x 5\) is NaN"):
        sample([volume, broken], np.stack([x, x]))
    with pytest.raises(ValueError, match="2 volume frames for 1 surface frames"):
        sample([volume, volume])
    with pytest.raises(ValueError, match="voxel size must be three positive, normal numbers"):
        sample(voxel_size=(1.0, -1.5, 3.0))
    with pytest.raises(ValueError, match="voxel_size must be three numbers"):
        sample(voxel_size=(1.0, 1.5))
    with pytest.raises(ValueError, match="layer 9 of a shell of 9 layers"):
        sample(reduce="layer:9")
    with pytest.raises(ValueError, match="reduce: 'median': expected max, mean or layer:L"):
        sample(reduce="median")
    with pytest.raises(ValueError, match="at least one layer"):
        sample(layers=0)
    with pytest.raises(ValueError, match="two distances ≥ 0"):
        sample(shell=(-1.0, 2.0))
    with pytest.raises(ValueError, match="smoothing σ must be a number ≥ 0"):
        sample(smoothing=-1.0)
    with pytest.raises(ValueError, match="must be numbers"):
        sample([volume > 0])
    with pytest.raises(ValueError, match=r"volumes\[0\] has shape \(40, 40\)"):
        sample([volume[0]])
    with pytest.raises(ValueError, match="face 0 refers to vertex 642, but the mesh has 642"):
        meshflow.sample_volume([volume], x[None], faces + len(x), VOXEL, origin=ORIGIN)


def test_points_and_volumes_to_a_scored_flow():
    """fit_surface → sample_volume → compute_flow → score_tracks on a texture turning about
    the z axis through the centre of a sphere cap: the flow follows the turn."""
    centre, radius, omega, frames = np.array([19.5, 19.5, 14.0]), 16.0, 0.05, 3

    def turned(p, angle):
        c, s = np.cos(angle), np.sin(angle)
        q = p - centre
        return np.stack([c * q[..., 0] - s * q[..., 1], s * q[..., 0] + c * q[..., 1],
                         q[..., 2]], axis=-1) + centre

    def texture(p):
        q = p - centre
        return np.sin(0.5 * q[..., 0]) * np.cos(0.4 * q[..., 1]) + 0.5 * np.sin(0.3 * q[..., 2])

    voxel = np.array([1.0, 1.0, 2.0])
    k, j, i = np.meshgrid(np.arange(20), np.arange(40), np.arange(40), indexing="ij")
    grid = np.stack([i, j, k], axis=-1) * voxel                       # (z, y, x, 3) centres
    volumes = np.stack([texture(turned(grid, -omega * f)) for f in range(frames)])
    cells = [cap_points(300 - 20 * f, radius, centre, 60) for f in range(frames)]

    surface = meshflow.fit_surface(cells, vertices=2000)
    positions, faces = surface["positions"], surface["faces"]
    sampled = meshflow.sample_volume(volumes, positions, faces, voxel)
    assert sampled["outside"] == [0] * frames
    flow = meshflow.compute_flow(positions, faces, sampled["values"])
    vectors = flow.vectors
    assert vectors.shape == (frames - 1, positions.shape[1], 3)
    assert np.isfinite(vectors).all()
    # Scored at material points turning with the texture.
    tracks = np.stack([turned(cap_points(60, radius, centre, 45), omega * f)
                       for f in range(frames)])
    scores = meshflow.score_tracks(flow, tracks)
    assert scores["points"] == 60 * (frames - 1)
    # Measured: endpoint ratio 0.10, median direction error 2.5°, median speed ratio 0.93.
    assert scores["endpoint_ratio"] < 0.25
    assert scores["median_direction_degrees"] < 8
    assert 0.8 < scores["median_speed_ratio"] < 1.1


def _ball_stack(shift=0.0):
    """A (40, 40, 40) image: 100 inside the ellipsoid of semi-axes (13, 11, 9) about the
    centre shifted by ``shift`` voxels along x, 0 outside."""
    z, y, x = np.meshgrid(*(np.arange(40.0),) * 3, indexing="ij")
    c = 19.5
    r = np.sqrt(((x - c - shift) / 13) ** 2 + ((y - c) / 11) ** 2 + ((z - c) / 9) ** 2)
    return np.where(r < 1.0, 100.0, 0.0)


def test_find_surface_bounds_a_solid_object_and_the_cli_agrees(cli, tmp_path):
    stack = _ball_stack()
    found = meshflow.find_surface(stack, (0.5, 0.5, 0.5), level=50.0, smoothing=0.5)
    p = found["positions"] / 0.5 - 19.5  # voxels, about the centre
    r = np.sqrt((p[:, 0] / 13) ** 2 + (p[:, 1] / 11) ** 2 + (p[:, 2] / 9) ** 2)
    assert np.abs(r - 1.0).max() < 0.05
    assert found["faces"].shape[1] == 3 and found["faces"].max() == len(p) - 1
    assert found["threshold"] == 50.0 and found["component_share"] == 1.0
    assert found["layer_vertices"] == 0  # solid: its boundary
    np.save(tmp_path / "stack.npy", np.stack([stack, _ball_stack(1.0)]))
    run(cli, "surface", tmp_path / "stack.npy", "--shape", "closed", "--level", "50",
        "--smooth", "0.5", "--voxel-size", "0.5,0.5,0.5", "--out", tmp_path / "s")
    report = json.loads((tmp_path / "s" / "surface.json").read_text())
    assert report["frames"][0]["vertices"] == len(p)
    assert report["frames"][0]["threshold"] == 50.0


def test_find_surface_errors():
    with pytest.raises(ValueError, match="the image is constant"):
        meshflow.find_surface(np.ones((8, 8, 8)))
    with pytest.raises(ValueError, match="give level below the object"):
        meshflow.find_surface(_ball_stack(), level=500.0)
    with pytest.raises(ValueError, match="level must be"):
        meshflow.find_surface(_ball_stack(), level=[1])
    with pytest.raises(ValueError, match="level: 'high' is not a number or 'auto'"):
        meshflow.find_surface(_ball_stack(), level="high")


def _write_ome_zarr(path, volumes, voxel, origin):
    """NGFF 0.5 (Zarr v3, uncompressed float32, one chunk per frame) of (K, Z, Y, X)
    ``volumes`` with the voxel size and origin as its scale and translation."""
    import os

    k, z, y, x = volumes.shape
    os.makedirs(path / "s0")
    transforms = [{"type": "scale", "scale": [1.0, voxel[2], voxel[1], voxel[0]]},
                  {"type": "translation", "translation": [0.0, origin[2], origin[1], origin[0]]}]
    axes = [{"name": "t", "type": "time"}] + [
        {"name": n, "type": "space", "unit": "micrometer"} for n in "zyx"]
    group = {"zarr_format": 3, "node_type": "group", "attributes": {"ome": {
        "version": "0.5", "multiscales": [{"version": "0.5", "axes": axes, "datasets": [
            {"path": "s0", "coordinateTransformations": transforms}]}]}}}
    (path / "zarr.json").write_text(json.dumps(group))
    array = {"zarr_format": 3, "node_type": "array", "shape": [k, z, y, x],
             "data_type": "float32",
             "chunk_grid": {"name": "regular", "configuration": {"chunk_shape": [1, z, y, x]}},
             "chunk_key_encoding": {"name": "default", "configuration": {"separator": "/"}},
             "fill_value": 0.0, "codecs": [{"name": "bytes", "configuration": {"endian": "little"}}]}
    (path / "s0" / "zarr.json").write_text(json.dumps(array))
    for t in range(k):
        chunk = path / "s0" / "c" / str(t) / "0" / "0" / "0"
        chunk.parent.mkdir(parents=True)
        chunk.write_bytes(volumes[t].astype("<f4").tobytes())


def test_volumes_on_disk_are_read_and_sampled_a_frame_at_a_time(ball, tmp_path):
    """A path to an .npy or an OME-Zarr image samples as the same arrays do, the Zarr
    image's voxel size and origin from its metadata; read_volumes picks frames; find_surface
    reads one frame of a path."""
    x, faces, _ = ball
    positions = np.stack([x, x + [2.0, 3.0, -1.0]])
    volume = linear_volume().astype(np.float32)
    volumes = np.stack([volume, volume + 1.0])
    np.save(tmp_path / "stack.npy", volumes)
    zarr = tmp_path / "stack.zarr"
    _write_ome_zarr(zarr, volumes, VOXEL, ORIGIN)
    options = {"smoothing": 1.5, "shell": (3.0, 3.0), "layers": 5}
    arrays = meshflow.sample_volume(volumes, positions, faces, VOXEL, origin=ORIGIN, **options)
    from_npy = meshflow.sample_volume(tmp_path / "stack.npy", positions, faces, VOXEL,
                                      origin=ORIGIN, **options)
    from_zarr = meshflow.sample_volume(str(zarr), positions, faces, **options)
    for sampled in (from_npy, from_zarr):
        assert np.array_equal(sampled["values"], arrays["values"])
        assert sampled["shell"] == arrays["shell"] and sampled["outside"] == [0, 0]
        assert sampled["voxel_size"] == VOXEL
    assert from_npy["voxel_size_source"] is None                 # given
    assert "micrometer" in from_zarr["voxel_size_source"]

    read = meshflow.read_volumes(zarr, frames=[1, 0, 1])
    assert read["volumes"].shape == (3, 20, 40, 40) and read["volumes"].dtype == np.float32
    assert np.array_equal(read["volumes"], volumes[[1, 0, 1]])
    assert read["voxel_size"] == VOXEL and read["origin"] == tuple(ORIGIN)
    with pytest.raises(ValueError, match=r"frame 2: the recording has frames 0 … 1"):
        meshflow.read_volumes(zarr, frames=[2])
    with pytest.raises(ValueError, match="channel=1: the image has channels 0 … 0"):
        meshflow.read_volumes(zarr, channel=1)
    with pytest.raises(ValueError, match="voxel_size is required with arrays"):
        meshflow.sample_volume(volumes, positions, faces)
    with pytest.raises(ValueError, match="apply to a path, not to arrays"):
        meshflow.sample_volume(volumes, positions, faces, VOXEL, channel=0)
    with pytest.raises(FileNotFoundError):
        meshflow.sample_volume(tmp_path / "missing.npy", positions, faces, VOXEL)

    ball_stack = np.stack([_ball_stack(), _ball_stack(1.0)]).astype(np.float32)
    np.save(tmp_path / "ball.npy", ball_stack)
    found = meshflow.find_surface(tmp_path / "ball.npy", (0.5, 0.5, 0.5), frame=1, level=50.0)
    direct = meshflow.find_surface(ball_stack[1], (0.5, 0.5, 0.5), level=50.0)
    assert np.array_equal(found["positions"], direct["positions"])
