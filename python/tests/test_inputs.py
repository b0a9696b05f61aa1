"""Inputs as users have them: dtypes, memory orders, views; the caller's arrays untouched."""

import numpy as np
import pytest

import meshflow


@pytest.fixture(scope="module")
def reference(sample):
    return sample.compute_flow(gamma=1e-3)


@pytest.mark.parametrize("face_dtype", [np.int32, np.int64, np.uint32, np.uint64])
def test_any_integer_faces(sample, reference, face_dtype):
    flow = meshflow.compute_flow(sample.positions, sample.faces.astype(face_dtype),
                                 sample.intensity, gamma=1e-3)
    assert np.array_equal(flow.vectors, reference.vectors)


def test_fortran_order_and_strided_views(sample, reference):
    positions = np.asfortranarray(sample.positions)
    faces = np.asfortranarray(sample.faces)
    padded = np.zeros((sample.intensity.shape[0], 2 * sample.intensity.shape[1]))
    padded[:, ::2] = sample.intensity
    intensity = padded[:, ::2]  # a non-contiguous view
    assert not intensity.flags.c_contiguous and not positions.flags.c_contiguous
    flow = meshflow.compute_flow(positions, faces, intensity, sample.times, gamma=1e-3)
    assert np.array_equal(flow.vectors, reference.vectors)


def test_float32_is_widened_exactly(sample):
    positions = sample.positions.astype(np.float32)
    intensity = sample.intensity.astype(np.float32)
    narrow = meshflow.compute_flow(positions, sample.faces, intensity, gamma=1e-3)
    wide = meshflow.compute_flow(positions.astype(np.float64), sample.faces,
                                 intensity.astype(np.float64), gamma=1e-3)
    assert np.array_equal(narrow.vectors, wide.vectors)


def test_lists_work_too(sample, reference):
    flow = meshflow.compute_flow(sample.positions.tolist(), sample.faces.tolist(),
                                 sample.intensity.tolist(), list(sample.times), gamma=1e-3)
    assert np.array_equal(flow.vectors, reference.vectors)


def test_the_callers_arrays_are_not_changed(sample):
    arrays = [sample.positions.copy(), sample.faces.astype(np.int32), sample.intensity.copy()]
    before = [a.copy() for a in arrays]
    for a in arrays:
        a.setflags(write=False)  # a write would raise
    meshflow.compute_flow(*arrays, gamma=1e-3)
    meshflow.operators(arrays[0][0], arrays[1])
    assert all(np.array_equal(a, b) for a, b in zip(arrays, before))


def test_results_are_in_the_input_numbering_when_welding_merges(sample):
    # Duplicate vertex 0 as a seam copy used by one face: welding merges it back.
    positions = np.concatenate([sample.positions, sample.positions[:, :1]], axis=1)
    intensity = np.concatenate([sample.intensity, sample.intensity[:, :1]], axis=1)
    faces = sample.faces.copy()
    face = np.nonzero((faces == 0).any(axis=1))[0][0]
    faces[face][faces[face] == 0] = len(sample.positions[0])
    flow = meshflow.compute_flow(positions, faces, intensity, gamma=1e-3)
    assert flow.vectors.shape == (5, 643, 3)
    assert np.array_equal(flow.vectors[:, -1], flow.vectors[:, 0])
    assert flow.vertex_map[-1] == flow.vertex_map[0] == 0
    unwelded = meshflow.compute_flow(positions, faces, intensity, gamma=1e-3, weld=False)
    assert np.array_equal(unwelded.vertex_map, np.arange(643))


def test_a_mesh_from_trimesh_style_arrays(sample):
    # trimesh.Trimesh.faces is int64 (F, 3) and vertices float64 (V, 3), C order.
    ops = meshflow.operators(np.ascontiguousarray(sample.positions[0]), sample.faces.astype(np.int64))
    assert ops["stiffness"].shape == (2 * 642, 2 * 642)


def test_anisotropic_auto_and_a_value(sample, reference):
    auto = meshflow.compute_flow(sample.positions, sample.faces, sample.intensity,
                                 gamma=1e-3, anisotropic="auto")
    huge = meshflow.compute_flow(sample.positions, sample.faces, sample.intensity,
                                 gamma=1e-3, anisotropic=1e12)
    # A huge λ is the isotropic term; auto smooths less across the texture's edges.
    assert np.allclose(huge.vectors, reference.vectors, rtol=0, atol=1e-9)
    assert np.abs(auto.vectors - reference.vectors).max() > 1e-6
    assert len(auto.anisotropic_contrasts) == sample.positions.shape[0] - 1
    assert huge.anisotropic_contrasts == [1e12] * (sample.positions.shape[0] - 1)


def test_anisotropic_in_time_weighs_the_coupling_in_time(sample, reference):
    def flow(**kw):
        return meshflow.compute_flow(sample.positions, sample.faces, sample.intensity,
                                     gamma=1e-3, anisotropic=kw.pop("lam"), **kw)
    # A huge λ: D_tt = 1, the paper's coupling; a finite one changes it.
    huge = flow(lam=1e12, anisotropic_in_time=True)
    assert np.allclose(huge.vectors, reference.vectors, rtol=0, atol=1e-9)
    plain, in_time = flow(lam=0.1), flow(lam=0.1, anisotropic_in_time=True)
    assert np.abs(in_time.vectors - plain.vectors).max() > 1e-6


def test_robust_smoothness_auto_records_its_scale_per_slab(sample):
    flow = meshflow.compute_flow(sample.positions, sample.faces, sample.intensity,
                                 robust_smoothness="auto")
    assert flow.reweightings >= 1
    assert len(flow.robust_scales) == sample.positions.shape[0] - 1
    assert all(e > 0 for e in flow.robust_scales)


def test_robust_data_and_the_motion_check_reach_the_solver(sample):
    flow = meshflow.compute_flow(sample.positions, sample.faces, sample.intensity,
                                 robust_data="auto")
    assert flow.reweightings >= 1
    assert len(flow.robust_data_scales) == sample.positions.shape[0] - 1
    assert all(e > 0 for e in flow.robust_data_scales)
    check = flow.large_motion
    assert check is not None and not check["warped"]
    assert 0 <= check["linearization_error"] < check["threshold"]
    never = meshflow.compute_flow(sample.positions, sample.faces, sample.intensity,
                                  large_motion=False)
    assert never.large_motion is None


def test_flow_driven_anisotropic_with_a_huge_scale_is_the_quadratic_flow(sample, reference):
    flow = meshflow.compute_flow(sample.positions, sample.faces, sample.intensity, gamma=1e-3,
                                 robust_smoothness=1e9, flow_driven="anisotropic")
    assert flow.reweightings >= 1
    assert np.allclose(flow.vectors, reference.vectors, rtol=0, atol=1e-8)


def test_the_callers_floating_point_mode_is_untouched(sample):
    # The solver flushes subnormal numbers while it runs, and restores the caller's mode.
    tiny = np.float32(np.finfo(np.float32).tiny)
    assert tiny * np.float32(0.5) > 0
    meshflow.compute_flow(sample.positions, sample.faces, sample.intensity, time_scale=0.01)
    assert tiny * np.float32(0.5) > 0
    assert np.nextafter(np.float64(0), np.float64(1)) > 0
