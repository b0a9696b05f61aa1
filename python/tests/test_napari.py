"""The napari plugin (meshflow.napari): the reader's layers against the run's files, the writer
read back, the pipeline against the command line, and, in a shown viewer (Xvfb in CI), the
plugin's reader, sample data, screenshot, widget, its responsiveness and its Cancel.

The layer tests need only NumPy; the viewer tests need napari, a Qt binding and pytest-qt
(``pip install "./python[napari]" pyqt6 pytest-qt``). Where those are missing the viewer tests
are skipped with the reason, unless MESHFLOW_NAPARI_TESTS=required (CI), which fails them."""

import json
import os
import pathlib
import time

import numpy as np
import pytest

import meshflow
from meshflow.napari import _layers, _reader, _writer
from meshflow.napari._pipeline import Cancelled, PipelineOptions, flow_from_recording
from meshflow.napari._sample_data import SHELL_TURN, shell_stack

from conftest import SAMPLE, run

SHELL_VOXEL = (1.0, 1.0, 1.5)


def needs_napari():
    """napari with pytest-qt, or the test's skip (a failure where CI requires them)."""
    try:
        import napari  # noqa: F401
        import pytestqt  # noqa: F401
    except ImportError as missing:
        if os.environ.get("MESHFLOW_NAPARI_TESTS") == "required":
            pytest.fail(f"the napari tests are required here: {missing}")
        pytest.skip(f"napari tests need napari and pytest-qt: {missing}")


@pytest.fixture(scope="module")
def sample_run(cli, tmp_path_factory):
    """The shipped sample solved by the CLI with its ground truth, then analysed and advected."""
    root = tmp_path_factory.mktemp("runs")
    solved = root / "sample"
    run(cli, "solve", SAMPLE, "--out", solved, "--ground-truth", SAMPLE / "ground_truth.npy", "--quiet")
    run(cli, "analyze", solved, "--out", root / "analysis", "--quiet")
    run(cli, "advect", solved, "--out", root / "paths", "--quiet")
    return root


@pytest.fixture(scope="module")
def shell_runs(cli, tmp_path_factory):
    """The synthetic shell stack, through the CLI (surface, sample, solve) and the pipeline."""
    root = tmp_path_factory.mktemp("shell")
    stack = root / "shell.npy"
    np.save(stack, shell_stack(voxel_size=SHELL_VOXEL))
    voxel = ",".join(str(v) for v in SHELL_VOXEL)
    run(cli, "surface", stack, "--shape", "closed", "--voxel-size", voxel, "--vertices", 1500, "--out", root / "seq", "--quiet")
    run(cli, "sample", stack, root / "seq", "--voxel-size", voxel, "--quiet")
    run(cli, "solve", root / "seq", "--out", root / "cli_run", "--quiet")
    options = PipelineOptions(voxel_size=SHELL_VOXEL, vertices=1500)
    result = flow_from_recording(stack, root / "pipeline_run", options)
    return root, result


def frame_vertices(layer_data):
    (vertices, faces, values), kwargs, kind = layer_data
    assert kind == "surface"
    return vertices, faces, values


def test_the_surface_layer_holds_the_runs_input_exactly(sample_run):
    layers = {kwargs["name"]: (data, kwargs, kind) for data, kwargs, kind in _layers.run_layers(sample_run / "sample")}
    sequence = meshflow.load_sequence(SAMPLE)
    vertices, faces, values = frame_vertices(layers["sample: surface"])
    k, v = sequence.positions.shape[:2]
    assert vertices.shape == (k * v, 4)
    # (t, z, y, x): the frame index, then meshflow's (x, y, z) reversed.
    np.testing.assert_array_equal(vertices[:, 0], np.repeat(np.arange(k), v))
    np.testing.assert_array_equal(vertices[:, 1:], sequence.positions[:, :, ::-1].reshape(-1, 3))
    np.testing.assert_array_equal(faces, (sequence.faces[None] + v * np.arange(k)[:, None, None]).reshape(-1, 3))
    np.testing.assert_array_equal(values, sequence.intensity.reshape(-1))
    assert layers["sample: surface"][1]["metadata"]["times"] == sequence.times.tolist()


def test_the_flow_layer_holds_flow_npy_at_its_arrows(sample_run):
    layers = {kwargs["name"]: (data, kwargs, kind) for data, kwargs, kind in _layers.run_layers(sample_run / "sample", arrows=None)}
    data, kwargs, kind = layers["sample: flow"]
    assert kind == "vectors" and kwargs["vector_style"] == "arrow"
    flow = np.load(sample_run / "sample" / "flow.npy")
    positions = meshflow.load_sequence(SAMPLE).positions
    s, v, _ = flow.shape
    assert data.shape == (s * v, 2, 4)
    vertex, slab = kwargs["features"]["vertex"], kwargs["features"]["slab"]
    np.testing.assert_array_equal(data[:, 1, 1:], flow[slab, vertex][:, ::-1])
    np.testing.assert_array_equal(data[:, 0, 1:], positions[slab, vertex][:, ::-1])
    np.testing.assert_array_equal(data[:, 0, 0], slab)
    assert np.all(data[:, 1, 0] == 0)
    # The PNGs' reference arrow is as long as the arrows' spacing: one per vertex here, on a
    # sphere of radius 1 (its area 4π less the icosphere's flat faces).
    speeds = np.linalg.norm(flow, axis=2).reshape(-1)
    spacing = kwargs["length"] * _layers.arrow_scale(speeds)
    assert spacing == pytest.approx(np.sqrt(4 * np.pi / v), rel=0.01)


def test_fewer_arrows_spread_over_the_surface(sample_run):
    (data, kwargs, _), = [d for d in _layers.run_layers(sample_run / "sample", arrows=100) if d[2] == "vectors"]
    per_slab = np.bincount(kwargs["features"]["slab"])
    assert np.all((per_slab >= 50) & (per_slab <= 200)), per_slab
    flow = np.load(sample_run / "sample" / "flow.npy")
    vertex, slab = kwargs["features"]["vertex"], kwargs["features"]["slab"]
    np.testing.assert_array_equal(data[:, 1, 1:], flow[slab, vertex][:, ::-1])


def test_analysis_and_trajectories_open_on_their_surface(sample_run):
    layers = {kwargs["name"]: (data, kwargs, kind) for data, kwargs, kind in _layers.run_layers(sample_run / "analysis")}
    divergence = np.load(sample_run / "analysis" / "divergence.npy")
    _, _, values = frame_vertices(layers["analysis: divergence"])
    np.testing.assert_array_equal(values, divergence.reshape(-1))
    low, high = layers["analysis: divergence"][1]["contrast_limits"]
    assert low == -high > -np.inf and high > 0
    assert not layers["analysis: curl"][1]["visible"]
    # Per-face areal rates become area-weighted vertex means: a constant stays that constant.
    surface = _layers.Surface.of(_layers.read_run(sample_run / "analysis")["surface"])
    np.testing.assert_allclose(surface.face_to_vertex(np.full(len(surface.faces), 0.25), 0), 0.25, rtol=1e-14)

    paths = _layers.run_layers(sample_run / "paths", tracks=None)
    (tracks, kwargs, _), = [d for d in paths if d[2] == "tracks"]
    trajectories = np.load(sample_run / "paths" / "trajectories.npy")
    k, n, _ = trajectories.shape
    assert tracks.shape == (k * n, 5)
    ids, frames = tracks[:, 0].astype(int), tracks[:, 1].astype(int)
    np.testing.assert_array_equal(tracks[:, 2:], trajectories[frames, ids][:, ::-1])


def test_scored_cells_open_as_points_and_two_displacements(cli, tmp_path):
    # Tracks of three vertices of the sample, moved as the texture turns: the run scores them.
    sequence = meshflow.load_sequence(SAMPLE)
    chosen = [5, 100, 300]
    tracks = np.stack([sequence.positions[k, chosen] for k in range(6)])
    np.save(tmp_path / "tracks.npy", tracks)
    out = tmp_path / "scored"
    run(cli, "solve", SAMPLE, "--out", out, "--ground-truth-tracks", tmp_path / "tracks.npy", "--quiet")
    layers = {kwargs["name"]: (data, kwargs, kind) for data, kwargs, kind in _layers.run_layers(out)}
    points, kwargs, kind = layers["scored: cells"]
    rows = (out / "track_errors.csv").read_text().splitlines()
    assert kind == "points" and points.shape == (len(rows) - 1, 4)
    header = rows[0].split(",")
    first = dict(zip(header, rows[1].split(",")))
    np.testing.assert_array_equal(points[0], [float(first[c]) for c in ("frame", "z", "y", "x")])
    true, _, _ = layers["scored: true displacement"]
    np.testing.assert_array_equal(true[0, 1, 1:], [float(first[c]) for c in ("true_z", "true_y", "true_x")])
    assert kwargs["features"]["endpoint_error"][0] == float(first["endpoint_error"])


def test_the_reader_takes_runs_and_leaves_other_directories(sample_run, tmp_path):
    assert _reader.napari_get_reader(str(sample_run / "sample")) is not None
    assert _reader.napari_get_reader(str(sample_run / "sample" / "meshflow_run.json")) is not None
    assert _reader.napari_get_reader(str(SAMPLE)) is None
    assert _reader.napari_get_reader(str(tmp_path)) is None
    assert _reader.napari_get_reader([str(sample_run / "sample"), str(SAMPLE)]) is None


def test_the_reader_keeps_to_the_file_policy(sample_run, tmp_path):
    # A run whose manifest lists a file outside it, or whose flow is a link out of it, is refused.
    import shutil

    planted = tmp_path / "planted"
    shutil.copytree(sample_run / "sample", planted)
    manifest = json.loads((planted / "meshflow_run.json").read_text())
    manifest["files"].append("../secret.npy")
    (planted / "meshflow_run.json").write_text(json.dumps(manifest))
    with pytest.raises(ValueError, match="secret.npy"):
        _layers.run_layers(planted)

    linked = tmp_path / "linked"
    shutil.copytree(sample_run / "sample", linked)
    outside = tmp_path / "outside.npy"
    np.save(outside, np.zeros((5, 642, 3)))
    (linked / "flow.npy").unlink()
    (linked / "flow.npy").symlink_to(outside)
    with pytest.raises(ValueError, match="flow.npy"):
        _layers.run_layers(linked)

    absolute = tmp_path / "absolute"
    shutil.copytree(sample_run / "sample", absolute)
    manifest = json.loads((absolute / "meshflow_run.json").read_text())
    manifest["solve"]["input"] = str(SAMPLE.resolve())
    (absolute / "meshflow_run.json").write_text(json.dumps(manifest))
    with pytest.raises(ValueError, match="absolute path"):
        _layers.run_layers(absolute)


def test_the_writer_reads_back_equal(sample_run, cli, tmp_path):
    layers = _layers.run_layers(sample_run / "sample", arrows=None)
    out = tmp_path / "written"
    assert _writer.write_layers(str(out), layers) == [str(out)]
    sequence = meshflow.load_sequence(SAMPLE)
    again = meshflow.load_sequence(out)
    np.testing.assert_array_equal(again.positions, sequence.positions)
    np.testing.assert_array_equal(again.faces, sequence.faces)
    np.testing.assert_array_equal(again.intensity, sequence.intensity)
    np.testing.assert_array_equal(again.times, sequence.times)
    # Its layers are the layers it was written from.
    for (a, _, kind), (b, _, _) in zip(layers[:1], _layers.run_layers(out)[:1]):
        for x, y in zip(a, b):
            np.testing.assert_array_equal(x, y)
    # ParaView's files: one per frame, with the flow where the vectors start.
    from xml.etree import ElementTree

    frames = ElementTree.parse(out / "surface.pvd").getroot().findall(".//DataSet")
    assert [f.get("file") for f in frames] == [f"surface_{k:04}.vtu" for k in range(6)]
    names = [a.get("Name") for a in ElementTree.parse(out / "surface_0000.vtu").getroot().iter("DataArray")]
    assert "intensity" in names and "flow" in names
    # The command line solves it as it solved the sample.
    run(cli, "solve", out, "--out", tmp_path / "again", "--quiet")
    np.testing.assert_array_equal(np.load(tmp_path / "again" / "flow.npy"), np.load(sample_run / "sample" / "flow.npy"))
    # Written again: refused over a directory meshflow did not write, never half-written.
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "thesis.tex").write_text("mine")
    with pytest.raises(ValueError, match="thesis.tex"):
        _writer.write_layers(str(foreign), layers)
    assert sorted(p.name for p in foreign.iterdir()) == ["thesis.tex"]


def test_the_writer_refuses_what_is_not_one_moving_mesh():
    vertices = np.array([[0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]], dtype=float)
    with pytest.raises(ValueError, match="one frame"):
        _writer.write_layers("unused", [((vertices, np.array([[0, 1, 2]])), {"name": "s"}, "surface")])
    two = np.vstack([vertices, vertices + [1, 0, 0, 0]])
    faces = np.array([[0, 1, 2], [3, 5, 4]])
    with pytest.raises(ValueError, match="frame 1 has other faces"):
        _writer.write_layers("unused", [((two, faces), {"name": "s"}, "surface")])


def test_the_pipeline_equals_the_command_line(shell_runs):
    root, result = shell_runs
    for name in ("flow.npy", "flow_intrinsic.npy", "velocity.npy"):
        np.testing.assert_array_equal(np.load(root / "pipeline_run" / name), np.load(root / "cli_run" / name))
    np.testing.assert_array_equal(result["positions"], np.load(root / "seq" / "positions.npy"))
    # Both runs name the recording: the reader opens it under the surface, in its voxel size.
    for run_dir in ("cli_run", "pipeline_run"):
        layers = {kind: (data, kwargs) for data, kwargs, kind in _layers.run_layers(root / run_dir)}
        image, kwargs = layers["image"]
        assert image.shape == (6, 48, 56, 56)
        assert kwargs["scale"] == (1.0, 1.5, 1.0, 1.0)
        np.testing.assert_array_equal(np.asarray(image[2]), np.load(root / "shell.npy")[2])
        # The surface lies on the shell (radius 17 about the box's centre).
        vertices, _, _ = layers["surface"][0]
        centre = np.array([47 * 1.5, 55.0, 55.0]) / 2
        radii = np.linalg.norm(vertices[:, 1:] - centre, axis=1)
        assert abs(np.median(radii) - 17.0) < 0.5


def test_the_recording_record_is_kept_and_checked(cli, shell_runs, tmp_path):
    import shutil

    root, _ = shell_runs
    # Drawing pictures into a run keeps the recording it names.
    run(cli, "render", root / "pipeline_run", "--slabs", "0", "--size", "64x48")
    manifest = json.loads((root / "pipeline_run" / "meshflow_run.json").read_text())
    assert manifest["recording"]["path"] == "../shell.npy"
    assert _layers.read_run(root / "pipeline_run")["recording"]["shape"] == [48, 56, 56]
    # A recording named by an absolute path is read only with allow_external_files.
    copied = tmp_path / "absolute"
    shutil.copytree(root / "pipeline_run", copied)
    manifest["recording"]["path"] = str((root / "shell.npy").resolve())
    (copied / "meshflow_run.json").write_text(json.dumps(manifest))
    with pytest.raises(ValueError, match="recording .* is an absolute path"):
        _layers.run_layers(copied)


def test_the_pipeline_measures_the_turn(shell_runs):
    # The shell turns about z by SHELL_TURN a frame: its material velocity is ω ẑ × (x − c).
    # The tracked mesh follows the spots' bumps part of the way (velocity.npy adds its motion
    # to the flow); the tangential part is what the image tells.
    root, _ = shell_runs
    velocity = np.load(root / "pipeline_run" / "velocity.npy")
    positions = np.load(root / "seq" / "positions.npy")[:-1]
    centre = np.array([55.0, 55.0, 47 * 1.5]) / 2
    truth = SHELL_TURN * np.cross([0.0, 0.0, 1.0], positions - centre)
    normal = (positions - centre) / np.linalg.norm(positions - centre, axis=2, keepdims=True)
    tangential = velocity - (velocity * normal).sum(axis=2, keepdims=True) * normal
    error = np.linalg.norm(tangential - truth, axis=2).mean() / np.linalg.norm(truth, axis=2).mean()
    assert error < 0.1, error


def test_the_pipeline_stops_when_asked(tmp_path):
    np.save(tmp_path / "shell.npy", shell_stack(voxel_size=SHELL_VOXEL))
    options = PipelineOptions(voxel_size=SHELL_VOXEL, vertices=1500)
    steps = []

    def stop_at_the_solve():
        return "solve" in steps

    with pytest.raises(Cancelled):
        flow_from_recording(
            tmp_path / "shell.npy",
            tmp_path / "run",
            options,
            progress=lambda e: steps.append(e.get("step")),
            should_stop=stop_at_the_solve,
        )
    assert steps[-1] == "solve" and not (tmp_path / "run").exists()


# ---------------------------------------------------------------- in a shown napari viewer


@pytest.fixture
def viewer(request):
    needs_napari()
    make_napari_viewer = request.getfixturevalue("make_napari_viewer")
    return make_napari_viewer(show=True)


def test_the_viewer_opens_a_run_with_the_plugin(viewer, sample_run):
    layers = viewer.open(str(sample_run / "sample"), plugin="meshflow")
    kinds = {layer.name: type(layer).__name__ for layer in layers}
    assert kinds == {"sample: surface": "Surface", "sample: flow": "Vectors"}
    viewer.dims.ndisplay = 3
    viewer.dims.set_current_step(0, 2)
    surface = viewer.layers["sample: surface"]
    assert surface._view_vertices.shape == (642, 3)
    np.testing.assert_array_equal(surface._view_vertices, meshflow.load_sequence(SAMPLE).positions[2][:, ::-1])
    shot = viewer.screenshot(canvas_only=True)[..., :3].astype(float)
    viewer.layers["sample: surface"].visible = False
    viewer.layers["sample: flow"].visible = False
    empty = viewer.screenshot(canvas_only=True)[..., :3].astype(float)
    assert shot.std() > 10, "uniform screenshot"
    assert np.abs(shot - empty).mean() > 5, "the surface does not show"


def test_the_sample_data_open_their_runs(viewer, tmp_path, monkeypatch):
    monkeypatch.setenv("MESHFLOW_SAMPLES", str(tmp_path))
    viewer.open_sample("meshflow", "turning_shell")
    kinds = sorted(type(layer).__name__ for layer in viewer.layers)
    assert kinds == ["Image", "Surface", "Vectors"]
    viewer.open_sample("meshflow", "rotating_sphere")
    assert (tmp_path / "rotating_sphere" / "flow.npy").is_file()
    assert (tmp_path / "turning_shell" / "run" / "meshflow_run.json").is_file()


def run_widget(qtbot, widget, stop_when=None, timeout=120.0):
    """Clicks Run, keeps the event loop turning with a 10 ms timer, and returns the longest gap
    between its ticks while the pipeline runs (the viewer's stalls; adding the results'
    layers afterwards is napari's drawing) once the widget reports done or failed."""
    from qtpy.QtCore import QTimer

    gaps, last = [0.0], [time.perf_counter(), False]

    def tick():
        now = time.perf_counter()
        running = widget.state.step is not None
        if running and last[1]:
            gaps.append(now - last[0])
        last[0], last[1] = now, running
        if stop_when is not None and stop_when():
            widget.cancel_button.clicked.emit()

    timer = QTimer()
    timer.timeout.connect(tick)
    timer.start(10)
    widget.run_button.clicked.emit()
    started = time.perf_counter()
    qtbot.waitUntil(lambda: widget.status.value.startswith(("done", "failed", "cancelled")), timeout=int(timeout * 1000))
    timer.stop()
    return max(gaps), time.perf_counter() - started


def test_the_widget_runs_the_pipeline_as_the_command_line(viewer, qtbot, shell_runs, tmp_path):
    from meshflow.napari._widget import make_widget

    root, _ = shell_runs
    viewer.add_image(np.load(root / "shell.npy"), scale=(1.0, 1.5, 1.0, 1.0), name="stack")
    widget = make_widget(viewer)
    viewer.window.add_dock_widget(widget)
    widget.controls["vertices"].value = 1500
    widget.controls["out"].value = str(tmp_path / "widget_run")
    stall, _ = run_widget(qtbot, widget)
    assert widget.status.value.startswith("done"), widget.status.value
    names = [layer.name for layer in viewer.layers]
    assert names[1:] == ["widget_run: surface", "widget_run: flow", "widget_run: divergence", "widget_run: curl", "widget_run: areal_rate"]
    flow = np.load(tmp_path / "widget_run" / "flow.npy")
    np.testing.assert_allclose(flow, np.load(root / "cli_run" / "flow.npy"), rtol=0, atol=1e-12)
    print(f"longest stall while the pipeline ran: {stall:.3f} s")
    assert stall < 0.2, f"the event loop stalled {stall:.2f} s"


def test_cancel_stops_the_widget_within_a_second(viewer, qtbot, shell_runs, tmp_path):
    from meshflow.napari._widget import make_widget

    root, _ = shell_runs
    viewer.add_image(np.load(root / "shell.npy"), scale=(1.0, 1.5, 1.0, 1.0), name="stack")
    widget = make_widget(viewer)
    widget.controls["vertices"].value = 1500
    widget.controls["out"].value = str(tmp_path / "cancelled_run")
    asked = []

    def at_the_solve():
        if widget.state.step == "solve" and not asked:
            asked.append(time.perf_counter())
            return True
        return False

    run_widget(qtbot, widget, stop_when=at_the_solve)
    stopped = time.perf_counter() - asked[0]
    print(f"stopped {stopped:.3f} s after Cancel")
    assert widget.status.value == "cancelled", widget.status.value
    assert stopped < 1.0, f"stopped {stopped:.2f} s after Cancel"
    assert not (tmp_path / "cancelled_run").exists()
