"""Behaviour in a Python program: progress, exceptions from callbacks, Ctrl-C, the GIL, and
tracking."""

import _thread
import signal
import threading

import numpy as np
import pytest

import meshflow

ITERATIVE = dict(gamma=1e-4, solver="pcg-jacobi", tolerance=1e-12)


def test_progress_reports_every_iteration(sample):
    events = []
    flow = sample.compute_flow(progress=events.append, **ITERATIVE)
    iterations = [e for e in events if e["kind"] == "iteration"]
    assert len(iterations) == flow.iterations > 10
    assert [e["iteration"] for e in iterations] == list(range(1, flow.iterations + 1))
    assert iterations[-1]["relative_residual"] <= 1e-12


def test_warping_reports_its_solves(sample):
    events = []
    sample.compute_flow(large_motion=True, progress=events.append)
    warps = [e for e in events if e["kind"] == "warp"]
    assert [e["solve"] for e in warps] == list(range(1, 9)) and warps[0]["solves"] == 8


def test_an_exception_in_the_callback_stops_the_solve(sample):
    class Enough(Exception):
        pass

    seen = []

    def stop_at_three(event):
        seen.append(event)
        if event.get("iteration") == 3:
            raise Enough()

    with pytest.raises(Enough):
        sample.compute_flow(progress=stop_at_three, **ITERATIVE)
    assert seen[-1]["iteration"] == 3  # stopped at once, not after the solve


def test_ctrl_c_interrupts_within_one_iteration(sample):
    # Python's own SIGINT handler, which a process started in the background by a
    # non-interactive shell (a CI runner) lacks: there SIGINT is ignored, and interrupt_main()
    # does nothing.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    seen = []

    def press_ctrl_c(event):
        seen.append(event)
        if event.get("iteration") == 5:
            _thread.interrupt_main()  # what Ctrl-C does: SIGINT's flag for the main thread

    try:
        with pytest.raises(KeyboardInterrupt):
            sample.compute_flow(progress=press_ctrl_c, **ITERATIVE)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert seen[-1]["iteration"] == 5
    sample.compute_flow(gamma=1e-3)  # and the next solve runs normally


def test_the_gil_is_released_while_solving(sample):
    positions = np.tile(sample.positions, (4, 1, 1))
    intensity = np.tile(sample.intensity, (4, 1))
    done = threading.Event()

    def solve():
        meshflow.compute_flow(positions, sample.faces, intensity, solver="pcg-jacobi", tolerance=1e-13)
        done.set()

    worker = threading.Thread(target=solve)
    worker.start()
    ticks = 0
    while not done.is_set():
        ticks += 1  # runs only while the solver does not hold the GIL
    worker.join()
    # A held GIL lets this loop run only at the thread switches before and after the solve.
    assert ticks > 10_000


def test_track_follows_frames_with_their_own_meshes(sample):
    shifted = [(p + [0.0, 0.0, 0.01 * k], sample.faces, g)
               for k, (p, g) in enumerate(zip(sample.positions, sample.intensity))]
    # Every other frame with its faces in another order: a different mesh of the same surface.
    order = np.random.default_rng(1).permutation(len(sample.faces))
    frames = [(p, f[order] if k % 2 else f, g) for k, (p, f, g) in enumerate(shifted)]
    tracked = meshflow.track(frames, times=sample.times)
    assert tracked.positions.shape == sample.positions.shape
    # Vertices move along their normals onto each shifted unit sphere (642-vertex icosphere:
    # its faces lie 0.987–1 from the centre).
    centres = np.array([[0.0, 0.0, 0.01 * k] for k in range(6)])
    radii = np.linalg.norm(tracked.positions - centres[:, None], axis=2)
    assert 0.985 < radii.min() and radii.max() < 1 + 1e-12
    assert len(tracked.report["frames"]) == 6 and tracked.report["max_step_bound"] > 0
    flow = tracked.compute_flow(gamma=1e-3)
    assert flow.vectors.shape == (5, 642, 3)
    with pytest.raises(ValueError, match="step bound"):
        meshflow.track(frames, max_step=-1)


def test_track_options_reach_the_library(sample):
    # Frame 1 is frame 0 turned by 10° about z and moved: rigid alignment finds the motion.
    angle = np.radians(10.0)
    turn = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]])
    squashed = sample.positions[0] * [1.0, 0.8, 0.6]   # an ellipsoid: rotations are seen
    frames = [(squashed, sample.faces, None), (squashed @ turn.T + [0.3, 0.0, 0.0], sample.faces, None)]
    tracked = meshflow.track(frames, align="rigid", reference_vertices=300)
    report = tracked.report
    assert 280 <= report["reference_vertices"] <= 320
    alignment = report["frames"][1]["alignment"]
    assert alignment["applied"] and abs(alignment["rotation_degrees"] - 10.0) < 0.1
    assert np.abs(tracked.positions[1] - tracked.positions[0]).max() < 1e-6
    plain = meshflow.track(frames, relax="none", keep_going=True)
    assert plain.report["relaxation"] is None
    assert any("looks misaligned" in w for w in plain.report["warnings"])
    with pytest.raises(ValueError, match="align must be"):
        meshflow.track(frames, align="affine")
    with pytest.raises(ValueError, match="relax must be"):
        meshflow.track(frames, relax="laplace")
