"""Microscopy workflows: tracks from point clouds, a flow scored at tracked points (the same
numbers as the CLI's summary.json)."""

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
