"""A moving-mesh sequence from any triangle mesh (OBJ): the mesh turns about its vertical (y)
axis by 1 degree per frame and breathes by 2 %, while a grey pattern slides over it (it turns
at 3 degrees per frame), so the flow is tangential and non-zero everywhere. For measuring the
solver on real scanned meshes, e.g. the public Stanford bunny of
github.com/alecjacobson/common-3d-test-models (data/stanford-bunny.obj, 35,947 vertices):

    python3 examples/sliding_pattern/make_sequence.py stanford-bunny.obj seq 20   # needs numpy
    meshflow solve seq --out out [--time-scale 30 | --alpha 0.01 --gamma 0.01]

Writes positions.npy (frames x vertices x 3), faces.npy and intensity.npy (grey values in
[0, 1]) into the output directory, which `meshflow solve DIR` reads. The mesh is centred and
scaled to unit size; vertices and faces are used as the file gives them (OBJ `v` and `f`
lines, 1-based, triangles)."""
import os, sys
import numpy as np

source, out = sys.argv[1], sys.argv[2]
frames = int(sys.argv[3]) if len(sys.argv) > 3 else 20
vertices, faces = [], []
for line in open(source):
    parts = line.split()
    if parts and parts[0] == "v":
        vertices.append([float(x) for x in parts[1:4]])
    elif parts and parts[0] == "f":
        faces.append([int(corner.split("/")[0]) - 1 for corner in parts[1:4]])
rest = np.array(vertices)
rest = (rest - rest.mean(0)) / np.ptp(rest, 0).max()


def turned(points, degrees):
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    return points @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]).T


positions, intensity = [], []
for t in range(frames):
    positions.append(turned(rest, 1.0 * t) * (1 + 0.02 * np.sin(2 * np.pi * t / frames)))
    p = turned(rest, 3.0 * t)
    intensity.append(0.5 + 0.5 * np.sin(12 * p[:, 0]) * np.sin(12 * p[:, 1] + 5 * p[:, 2]))
os.makedirs(out, exist_ok=True)
np.save(os.path.join(out, "positions.npy"), np.array(positions))
np.save(os.path.join(out, "faces.npy"), np.array(faces, dtype=np.int64))
np.save(os.path.join(out, "intensity.npy"), np.array(intensity))
print(f"{len(rest)} vertices, {len(faces)} faces, {frames} frames -> {out}")
