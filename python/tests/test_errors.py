"""Every library error is a Python exception with the CLI's one-line message."""

import numpy as np
import pytest

import meshflow
from conftest import ROOT


def solve(sample, **changes):
    arrays = dict(positions=sample.positions, faces=sample.faces, intensity=sample.intensity)
    arrays.update(changes)
    return meshflow.compute_flow(**arrays)


@pytest.mark.parametrize("changes, message", [
    (dict(intensity=np.zeros((6, 5))), "intensity has shape (6, 5), expected (6, 642)"),
    (dict(positions=np.zeros((6, 642))), "positions has shape (6, 642), expected (frames, vertices, 3)"),
    (dict(faces=np.zeros((4, 4), dtype=int)), "faces has shape (4, 4), expected (faces, 3)"),
    (dict(faces=np.zeros((4, 3))), "faces must be integers, got dtype float64"),
    (dict(positions=np.zeros((1, 642, 3)), intensity=np.zeros((1, 642))), "at least 2 frames"),
])
def test_bad_shapes(sample, changes, message):
    with pytest.raises(ValueError) as error:
        solve(sample, **changes)
    assert message in str(error.value)


def test_data_errors_name_the_frame_vertex_or_face(sample):
    grey = sample.intensity.copy()
    grey[2, 7] = np.nan
    with pytest.raises(ValueError, match=r"^arrays: frame 2: intensity at vertex 7 is NaN"):
        solve(sample, intensity=grey)
    positions = sample.positions.copy()
    positions[3, 5] = np.inf
    with pytest.raises(ValueError, match="frame 3"):
        solve(sample, positions=positions)
    faces = sample.faces.copy()
    faces[4, 1] = 9999
    with pytest.raises(ValueError, match="face 4"):
        solve(sample, faces=faces)
    faces[4, 1] = -1
    with pytest.raises(ValueError, match=r"faces\[4\] names vertex -1"):
        solve(sample, faces=faces)
    collapsed = sample.positions.copy()
    a, b, c = sample.faces[10]
    collapsed[:, c] = collapsed[:, a]  # triangle 10 degenerates in every frame
    with pytest.raises(ValueError, match="frame 0"):
        solve(sample, positions=collapsed)


def test_non_manifold_input_is_refused_and_repaired_on_request():
    # Three triangles on one edge (0, 1).
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]], float)
    faces = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    with pytest.raises(ValueError, match="repair=True"):
        meshflow.operators(positions, faces)
    ops = meshflow.operators(positions, faces, repair=True)
    assert ops["cotan"].shape[0] > 5  # the edge was cut: vertices split


@pytest.mark.parametrize("keywords, message", [
    (dict(gamma=-1.0), "gamma"),
    (dict(gamma=1e-3, spread=0.5), "give one of gamma and spread, not both"),
    (dict(solver="cholmod"), "solver: "),
    (dict(boundary="periodic"), "boundary: 'periodic' is not one of: neumann, dirichlet"),
    (dict(tolerance=0.0), "tolerance"),
    (dict(regularizer="tv"), "regularizer: 'tv' is not one of: covariant, strain, embedded"),
    (dict(dirichlet_mix=0.5), "only with the strain regularizer"),
    (dict(robust_smoothness=0.0), "robust_smoothness"),
    (dict(robust_smoothness="strong"), "robust_smoothness must be a number or 'auto'"),
    (dict(anisotropic=0.0), "anisotropy lambda"),
    (dict(anisotropic=1.0, regularizer="embedded"), "not the embedded regularizer"),
    (dict(anisotropic="sharp"), "anisotropic must be a number or 'auto', got 'sharp'"),
    (dict(anisotropic_sigma=1.0), "anisotropic_sigma needs anisotropic"),
    (dict(anisotropic_in_time=True), "anisotropic_in_time needs anisotropic"),
    (dict(anisotropic=1.0, anisotropic_sigma=-1.0), "anisotropy sigma"),
    (dict(flow_driven="anisotropic"), "give its scale with robust_smoothness"),
    (dict(flow_driven="sideways", robust_smoothness=0.1),
     "flow_driven: 'sideways' is not one of: isotropic, anisotropic"),
    (dict(levels=0), "level"),
    (dict(alpha="fast"), "alpha must be a number"),
    (dict(progress=3), "progress must be callable"),
])
def test_bad_parameters(sample, keywords, message):
    with pytest.raises(ValueError) as error:
        solve(sample, **keywords)
    assert message in str(error.value)


def test_file_errors_are_os_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="no_such_dir"):
        meshflow.load_sequence(tmp_path / "no_such_dir")
    broken = tmp_path / "broken"
    broken.mkdir()
    for k in range(2):
        (broken / f"frame_{k}.obj").write_text("v 0 0 0\nv 1 0 0\nf 1 2 3\n")
    with pytest.raises(ValueError, match="frame_0.obj"):
        meshflow.load_sequence(broken)
    with pytest.raises(ValueError, match="applies to a glTF animation"):
        meshflow.load_sequence(ROOT / "meshes" / "rotating_sphere", fps=10)


def test_write_outputs_refuses_what_it_did_not_write(sample, tmp_path):
    flow = sample.compute_flow(gamma=1e-3)
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match="force"):
        meshflow.write_outputs(flow, tmp_path)
    assert (tmp_path / "notes.txt").read_text() == "mine"
    meshflow.write_outputs(flow, tmp_path, force=True, formats="npy")
    assert (tmp_path / "flow.npy").exists() and (tmp_path / "notes.txt").exists()
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    with pytest.raises(OSError):
        meshflow.write_outputs(flow, blocker / "out")
    with pytest.raises(ValueError, match="unknown output format 'png'"):
        meshflow.write_outputs(flow, tmp_path / "x", formats=["png"])


def test_limits_guard_against_hostile_files(tmp_path):
    glb = ROOT / "meshes" / "rotating_sphere.glb"
    before = meshflow.set_limits()
    assert before["memory_limit"] > 1 << 30 and before["allow_external_files"] is False
    try:
        assert meshflow.set_limits(memory_limit="1K")["memory_limit"] == 1024
        with pytest.raises(ValueError, match=r"rotating_sphere\.glb: the file declares .* over the memory limit of 1.0 kB"):
            meshflow.load_sequence(glb)
        with pytest.raises(ValueError, match="not a size"):
            meshflow.set_limits(memory_limit="lots")
    finally:
        assert meshflow.set_limits(memory_limit="default")["memory_limit"] == before["memory_limit"]
    assert meshflow.load_sequence(glb).positions.shape[0] > 1
