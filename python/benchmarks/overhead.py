"""What calling meshflow from Python costs over calling the library from Rust.

    python python/benchmarks/overhead.py [RUNS]      (from the repository root)

Runs `cargo run --release --example bench_python`, which writes the level-5 rotating sphere
(10,242 vertices, 6 frames) as an NPY sequence and times `io::sequence_from_arrays` plus the
solve in Rust, then times `meshflow.compute_flow` on the same arrays (and reading its
`vectors`), alternating nothing else on the machine. Prints both medians and the ratio.
"""

import json
import pathlib
import statistics
import subprocess
import sys
import time

import numpy as np

import meshflow

ROOT = pathlib.Path(__file__).resolve().parents[2]


def main() -> None:
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    data = ROOT / "out" / "bench_python"
    rust = subprocess.run(
        ["cargo", "run", "--release", "--quiet", "--example", "bench_python", "--", str(data), str(runs)],
        cwd=ROOT, check=True, capture_output=True, text=True,
    )
    rust = json.loads(rust.stdout.strip().splitlines()[-1])
    positions = np.load(data / "positions.npy")
    faces = np.load(data / "faces.npy")
    intensity = np.load(data / "intensity.npy")
    times = np.loadtxt(data / "times.txt")
    python = []
    for _ in range(runs):
        start = time.perf_counter()
        flow = meshflow.compute_flow(positions, faces, intensity, times)
        flow.vectors
        python.append(time.perf_counter() - start)
    median = statistics.median(python)
    print(f"{rust['vertices']} vertices x {rust['frames']} frames, median of {runs}:")
    print(f"  Rust   {rust['median']:.3f} s  {['%.3f' % t for t in rust['runs']]}")
    print(f"  Python {median:.3f} s  {['%.3f' % t for t in python]}")
    print(f"  Python / Rust = {median / rust['median']:.3f}")


if __name__ == "__main__":
    main()
