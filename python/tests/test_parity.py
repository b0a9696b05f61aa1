"""What the command line does, Python does too: advect, pictures, geometry without an image,
runs that the command line can continue, and messages in Python's words."""

import json

import numpy as np
import pytest

import meshflow
from meshflow import _meshflow
from conftest import SAMPLE, run


def write_plain_obj(path, positions, faces):
    """An OBJ without colours: geometry only."""
    lines = [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in positions]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")


@pytest.fixture
def colourless(sample, tmp_path):
    """The sample's geometry as OBJ frames without colours."""
    directory = tmp_path / "plain"
    directory.mkdir()
    for k, positions in enumerate(sample.positions):
        write_plain_obj(directory / f"frame_{k}.obj", positions, sample.faces)
    return directory


def test_geometry_loads_without_an_image(sample, colourless):
    with pytest.raises(ValueError) as refused:
        meshflow.load_sequence(colourless)
    assert "intensity='FILE.npy'" in str(refused.value) and "--" not in str(refused.value)
    for loaded in (meshflow.load_sequence(colourless, image=False),
                   meshflow.load_mesh_sequence(colourless)):
        assert loaded.intensity is None
        np.testing.assert_array_equal(loaded.faces, sample.faces)
        np.testing.assert_allclose(loaded.positions, sample.positions, rtol=0, atol=1e-15)
        np.testing.assert_array_equal(loaded.times, np.arange(6.0))
    with pytest.raises(ValueError, match="without an image"):
        loaded.compute_flow()
    # The user's own values: the sample's image gives the sample's flow.
    loaded.intensity = sample.intensity
    flow = loaded.compute_flow()
    np.testing.assert_allclose(flow.vectors, sample.compute_flow().vectors, rtol=0, atol=1e-12)


def test_advect_equals_the_command_line(cli, sample, tmp_path):
    run(cli, "solve", SAMPLE, "--out", tmp_path / "run", "--format", "npy")
    run(cli, "advect", tmp_path / "run", "--out", tmp_path / "advected")
    flow = sample.compute_flow()
    paths = meshflow.advect(flow)
    expected = np.load(tmp_path / "advected" / "trajectories.npy")
    assert paths.positions.shape == (6, 642, 3)
    np.testing.assert_array_equal(paths.positions, expected)
    np.testing.assert_array_equal(
        paths.faces, np.load(tmp_path / "advected" / "trajectory_faces.npy"))
    np.testing.assert_array_equal(
        paths.barycentric, np.load(tmp_path / "advected" / "trajectory_barycentric.npy"))
    np.testing.assert_array_equal(
        paths.intensity, np.load(tmp_path / "advected" / "intensity.npy"))
    # Vertex seeds start at the vertices, and the image they see changes less than at rest.
    np.testing.assert_allclose(paths.positions[0], sample.positions[0], rtol=0, atol=1e-14)
    moving = np.abs(paths.intensity[-1] - paths.intensity[0]).mean()
    at_rest = np.abs(sample.intensity[-1] - sample.intensity[0]).mean()
    assert moving < 0.5 * at_rest, (moving, at_rest)
    assert paths.sequence.positions.shape == (6, 642, 3)
    np.testing.assert_array_equal(paths.sequence.faces, sample.faces)
    # Seeds: a point above vertex 7 starts at the surface near it.
    seeds = sample.positions[0][[7, 100]] * 1.01
    followed = meshflow.advect(flow, seeds)
    assert followed.sequence is None and followed.positions.shape == (6, 2, 3)
    np.testing.assert_allclose(followed.positions[0], sample.positions[0][[7, 100]], atol=2e-3)
    with pytest.raises(ValueError, match="point 1 has a non-finite coordinate"):
        meshflow.advect(flow, np.array([[0.0, 0, 1], [np.nan, 0, 0]]))


def test_render_draws_what_the_command_line_draws(cli, sample, tmp_path):
    run(cli, "solve", SAMPLE, "--out", tmp_path / "run", "--format", "npy", "--png")
    flow = sample.compute_flow()
    written = meshflow.render(flow, tmp_path / "pictures", slabs="0,last")
    names = sorted(p.rsplit("/", 1)[-1] for p in written)
    assert names == sorted(f"{kind}_{s:04d}.png" for kind in ("grey", "flow", "arrows")
                           for s in (0, 4))
    for name in names:
        assert (tmp_path / "pictures" / name).read_bytes() == \
            (tmp_path / "run" / name).read_bytes(), name
    # A list of slabs, another view, and a directory that is not meshflow's.
    assert len(meshflow.render(flow, tmp_path / "pictures", slabs=[2], view=(0, 90))) == 3
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    with pytest.raises(ValueError) as refused:
        meshflow.render(flow, tmp_path / "mine")
    assert "force=True" in str(refused.value) and "--force" not in str(refused.value)
    with pytest.raises(ValueError, match="slab 9"):
        meshflow.render(flow, tmp_path / "pictures", slabs="9")


def test_runs_written_from_python_are_runs_of_the_command_line(cli, sample, tmp_path):
    flow = sample.compute_flow()
    meshflow.write_outputs(flow, tmp_path / "py")
    # Moved elsewhere, the run still holds its input.
    (tmp_path / "py").rename(tmp_path / "moved")
    run(cli, "advect", tmp_path / "moved", "--out", tmp_path / "advected")
    np.testing.assert_array_equal(
        np.load(tmp_path / "advected" / "trajectories.npy"), meshflow.advect(flow).positions)
    run(cli, "render", tmp_path / "moved", "--slabs", "0")
    assert (tmp_path / "moved" / "flow_0000.png").exists()


def test_solves_of_large_motion_report_their_share(sample):
    flow = sample.compute_flow(large_motion=True)
    assert [s["label"] for s in flow.solves][-1] == "level 0, warp 2"
    assert len(flow.solves) == 8
    assert sum(s["seconds"] for s in flow.solves) <= flow.seconds["total"]
    assert all(s["iterations"] >= 1 for s in flow.solves)
    assert sample.compute_flow().solves == []


@pytest.mark.parametrize("cli_words, python_words", [
    ("give --intensity FILE.npy", "give intensity='FILE.npy'"),
    ("or add --force to write into it", "or add force=True to write into it"),
    ("fixes it: --speed-penalty 0.01 (relative), or --beta", "fixes it: speed_penalty=0.01 (relative), or beta"),
    ("use a smaller --weld-tolerance, or --no-weld", "use a smaller weld_tolerance, or weld=False"),
    ("run `meshflow track` on them first", "run meshflow.track() on them first"),
    ("(--spread, --time-scale)", "(spread, time_scale)"),
    ("x-- y and a--b stay", "x-- y and a--b stay"),
])
def test_messages_name_python_keywords(cli_words, python_words):
    assert _meshflow.python_words(cli_words) == python_words


def test_singular_problem_advice_names_keywords():
    positions = np.zeros((2, 3, 3))
    positions[:, 1, 0] = positions[:, 2, 1] = 1.0
    flat = np.ones((2, 3))
    with pytest.raises(ValueError) as refused:
        meshflow.compute_flow(positions, [[0, 1, 2]], flat)
    message = str(refused.value)
    assert "--" not in message, message


def test_word_values_of_flags_are_quoted():
    assert _meshflow.python_words("--channels rgb needs colours; use --channels auto or grey") \
        == "channels='rgb' needs colours; use channels='auto' or grey"
    assert _meshflow.python_words("try --align rigid, or --keep-going") \
        == "try align='rigid', or keep_going=True"


def test_analysis_equals_the_command_line(cli, sample, tmp_path):
    run(cli, "solve", SAMPLE, "--out", tmp_path / "run", "--format", "npy")
    run(cli, "analyze", tmp_path / "run", "--out", tmp_path / "analysis")
    result = meshflow.analyze(sample.compute_flow())
    for name in ["divergence", "curl", "potential", "stream", "face_divergence", "areal_rate",
                 "shear_rate", "principal_rates", "stretch_direction", "hodge_exact",
                 "hodge_coexact", "hodge_harmonic", "faces"]:
        np.testing.assert_array_equal(result[name], np.load(tmp_path / "analysis" / f"{name}.npy"))
    slabs = result["slabs"]
    assert len(slabs) == 5 and slabs[0]["slab"] == 0
    # A rotation is co-exact: J∇z.
    assert all(s["coexact_energy"] > 0.95 * s["energy"] for s in slabs)
    assert result["hodge_exact"].shape == (5, 1280, 3)


def test_the_solver_reports_the_spectrum_it_saw(sample, tmp_path):
    flow = sample.compute_flow(solver="pcg-time-multigrid")
    low, high = flow.preconditioned_spectrum
    # A V-cycle in time is a good preconditioner: its spectrum is positive and narrow, near 1
    # (above 1 by a little: the coarse levels' halved time coupling over-corrects some modes).
    assert 0.0 < low <= high < 1.5
    assert high / low < 10.0
    meshflow.write_outputs(flow, tmp_path / "run")
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["preconditioned_spectrum"] == [low, high]
    assert sample.compute_flow(solver="direct").preconditioned_spectrum is None
