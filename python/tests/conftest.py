"""Shared fixtures: the repository, the `meshflow` binary built by `cargo test --release`,
and the shipped rotating-sphere sample."""

import os
import pathlib
import subprocess

import pytest

import meshflow

ROOT = pathlib.Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "meshes" / "rotating_sphere"


@pytest.fixture(scope="session")
def cli() -> pathlib.Path:
    """The `meshflow` binary of this checkout (MESHFLOW_BIN overrides)."""
    binary = pathlib.Path(os.environ.get("MESHFLOW_BIN", ROOT / "target" / "release" / "meshflow"))
    if not binary.exists():
        subprocess.run(["cargo", "build", "--release", "--bin", "meshflow"], cwd=ROOT, check=True)
    return binary


@pytest.fixture(scope="session")
def sample() -> meshflow.Sequence:
    return meshflow.load_sequence(SAMPLE)


def run(cli: pathlib.Path, *args: object) -> subprocess.CompletedProcess:
    """Runs the CLI; fails the test with its stderr when it fails."""
    done = subprocess.run([str(cli), *map(str, args)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return done
