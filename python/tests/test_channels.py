"""Colour and multi-channel images from Python: (K, V, C) arrays, channels=, channel_weights=."""

import json

import numpy as np
import pytest

import meshflow


def test_three_equal_channels_give_the_grey_flow(sample):
    grey = sample.compute_flow()
    colour = np.repeat(sample.intensity[:, :, None], 3, axis=2)
    flow = meshflow.compute_flow(sample.positions, sample.faces, colour, sample.times)
    assert np.max(np.abs(flow.vectors - grey.vectors)) < 1e-9 * np.max(np.abs(grey.vectors))
    assert json.loads(flow.summary_json())["channels"] == 3


def test_channel_choices_and_weights(sample):
    noise = np.random.default_rng(1).random(sample.intensity.shape)
    stack = np.stack([noise, sample.intensity, noise], axis=2)
    grey = sample.compute_flow()
    # Only the middle channel counts: the grey flow again.
    picked = meshflow.compute_flow(sample.positions, sample.faces, stack, sample.times,
                                   channel_weights=[0, 1, 0])
    assert np.allclose(picked.vectors, grey.vectors, rtol=0, atol=1e-9)
    summary = json.loads(picked.summary_json())
    assert summary["params"]["channel_weights"] == [0.0, 1.0, 0.0]
    # luma of three channels is one channel; 'rgb' of a grey image is refused.
    luma = meshflow.compute_flow(sample.positions, sample.faces, stack, sample.times,
                                 channels="luma")
    assert json.loads(luma.summary_json())["channels"] == 1
    with pytest.raises(ValueError, match="channels='rgb' needs colours"):
        meshflow.compute_flow(sample.positions, sample.faces, sample.intensity, channels="rgb")
    with pytest.raises(ValueError, match="channels: 'hsv' is not one of"):
        meshflow.compute_flow(sample.positions, sample.faces, stack, channels="hsv")
    with pytest.raises(ValueError, match="expected 3 channel weights"):
        meshflow.compute_flow(sample.positions, sample.faces, stack, channel_weights=[1, 1])
    with pytest.raises(ValueError, match="intensity has shape"):
        meshflow.compute_flow(sample.positions, sample.faces, stack[:, :-1])


def test_loaded_colours_are_channels(tmp_path, sample):
    # An NPY sequence whose intensity.npy has a channel axis loads as (K, V, C).
    stack = np.stack([sample.intensity, 1 - sample.intensity], axis=2)
    np.save(tmp_path / "positions.npy", sample.positions)
    np.save(tmp_path / "faces.npy", sample.faces)
    np.save(tmp_path / "intensity.npy", stack)
    loaded = meshflow.load_sequence(tmp_path)
    assert loaded.intensity.shape == stack.shape
    assert np.array_equal(loaded.intensity, stack)
    mean = meshflow.load_sequence(tmp_path, channels="grey")
    assert mean.intensity.shape == sample.intensity.shape
    assert np.allclose(mean.intensity, 0.5)
    assert loaded.compute_flow().vectors.shape == (sample.positions.shape[0] - 1,) + sample.positions.shape[1:]
