"""The package computes what the CLI and the library compute, bit for bit."""

import json

import numpy as np
import scipy.io

import meshflow
from conftest import ROOT, SAMPLE, run


def test_flow_equals_the_cli_bit_for_bit(cli, sample, tmp_path):
    run(cli, "solve", SAMPLE, "--out", tmp_path / "cli", "--format", "npy")
    flow = sample.compute_flow()
    assert np.array_equal(flow.vectors, np.load(tmp_path / "cli" / "flow.npy"))
    assert np.array_equal(flow.intrinsic, np.load(tmp_path / "cli" / "flow_intrinsic.npy"))
    summary = json.loads((tmp_path / "cli" / "summary.json").read_text())
    assert flow.energy == summary["energy"]
    assert flow.weights["gamma"] == summary["weights"]["gamma"]


def test_keywords_reach_the_solver_as_the_cli_flags_do(cli, sample, tmp_path):
    flags = ["--gamma", "1e-3", "--time-scale", "2", "--boundary", "dirichlet",
             "--time-coupling", "consistent", "--solver", "pcg-slab-gauss-seidel",
             "--tolerance", "1e-10", "--levels", "2", "--warps", "1",
             "--regularizer", "strain", "--dirichlet-mix", "0.25", "--robust-smoothness", "0.05",
             "--robust-data", "0.5", "--median-filter", "--local-integration", "0.2"]
    run(cli, "solve", SAMPLE, "--out", tmp_path / "cli", "--format", "npy", *flags)
    flow = sample.compute_flow(gamma=1e-3, time_scale=2, boundary="dirichlet",
                               time_coupling="consistent", solver="pcg-slab-gauss-seidel",
                               tolerance=1e-10, levels=2, warps=1,
                               regularizer="strain", dirichlet_mix=0.25, robust_smoothness=0.05,
                               robust_data=0.5, median_filter=True, local_integration=0.2)
    assert np.array_equal(flow.vectors, np.load(tmp_path / "cli" / "flow.npy"))
    assert flow.warped_residual is not None and flow.warped_residual.shape == (5, 642)
    summary = json.loads(flow.summary_json())
    assert summary["params"]["regularizer"] == {"kind": "strain", "dirichlet": 0.25}
    assert summary["params"]["robust_smoothness"] == 0.05
    assert summary["params"]["robust_data"] == 0.5 and summary["params"]["median_filter"]
    assert summary["params"]["local_integration"] == 0.2
    assert flow.reweightings >= 1 and summary["reweightings"] == flow.reweightings


def test_operators_equal_the_cli_bit_for_bit(cli, tmp_path):
    mesh = ROOT / "meshes" / "torus.obj"
    run(cli, "operators", mesh, "--out", tmp_path)
    positions, faces = read_obj(mesh)
    ops = meshflow.operators(positions, faces)
    for name in ["cotan", "mass_scalar", "stiffness", "mass"]:
        written = scipy.io.mmread(tmp_path / f"{name}.mtx").tocsc()
        assert (ops[name] != written).nnz == 0, name
    assert np.array_equal(ops["frames"], np.load(tmp_path / "frames.npy"))
    assert np.array_equal(ops["vertex_map"], np.arange(len(positions)))


def test_operators_keep_their_documented_signs(sample):
    ops = meshflow.operators(sample.positions[0], sample.faces)
    ones = np.ones(ops["cotan"].shape[0])
    assert np.abs(ops["cotan"] @ ones).max() < 1e-12  # L·1 = 0
    area = ones @ ops["mass_scalar"] @ ones  # 1ᵀm1 = area of the unit icosphere
    assert abs(area - 4 * np.pi) < 0.05 * 4 * np.pi
    for name in ["cotan", "stiffness", "mass"]:
        assert abs(ops[name] - ops[name].T).max() < 1e-14
    frames = ops["frames"]
    gram = np.einsum("ikj,ilj->ikl", frames, frames)
    assert np.abs(gram - np.eye(2)).max() < 1e-12


def test_load_sequence_round_trips_an_npy_directory(sample, tmp_path):
    np.save(tmp_path / "positions.npy", sample.positions)
    np.save(tmp_path / "faces.npy", sample.faces.astype(np.int32))
    np.save(tmp_path / "intensity.npy", sample.intensity.astype(np.float32))
    np.savetxt(tmp_path / "times.txt", 0.5 * sample.times)
    again = meshflow.load_sequence(tmp_path)
    assert np.array_equal(again.positions, sample.positions)
    assert np.array_equal(again.faces, sample.faces)
    assert np.array_equal(again.intensity, sample.intensity.astype(np.float32))
    assert np.array_equal(again.times, 0.5 * sample.times)
    assert again.source == "NPY arrays"


def test_load_sequence_reads_what_solve_reads(sample):
    glb = meshflow.load_sequence(ROOT / "meshes" / "rotating_sphere.glb")
    assert glb.source == "glTF animation"
    assert glb.positions.shape[1:] == (642, 3) and glb.times.shape == (glb.positions.shape[0],)
    retimed = meshflow.load_sequence(SAMPLE, times=[0, 2, 4, 6, 8, 10])
    assert np.array_equal(retimed.times, [0, 2, 4, 6, 8, 10])
    assert np.array_equal(sample.vertex_map, np.arange(642))


def test_write_outputs_writes_what_solve_writes(cli, sample, tmp_path):
    run(cli, "solve", SAMPLE, "--out", tmp_path / "cli")
    flow = sample.compute_flow()
    meshflow.write_outputs(flow, tmp_path / "py")
    for name in ["flow.npy", "flow_intrinsic.npy"]:
        assert np.array_equal(np.load(tmp_path / "py" / name), np.load(tmp_path / "cli" / name))
    written = sorted(p.name for p in (tmp_path / "py").iterdir())
    assert {"flow.pvd", "flow.glb", "summary.json", "flow_0000.vtu"} <= set(written)
    summary = json.loads((tmp_path / "py" / "summary.json").read_text())
    assert summary["input"] == "arrays in memory"
    meshflow.write_outputs(flow, tmp_path / "py", formats=["npy"])  # replaces its own output
    assert not (tmp_path / "py" / "flow.pvd").exists()


def read_obj(path):
    """Vertices and triangles of an OBJ, independently of meshflow's reader."""
    positions, faces = [], []
    for line in path.read_text().splitlines():
        fields = line.split()
        if fields[:1] == ["v"]:
            positions.append([float(x) for x in fields[1:4]])
        elif fields[:1] == ["f"]:
            faces.append([int(x.split("/")[0]) - 1 for x in fields[1:4]])
    return np.array(positions), np.array(faces)
