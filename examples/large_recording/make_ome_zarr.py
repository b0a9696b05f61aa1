"""A large recording as OME-Zarr (NGFF 0.5, Zarr v3, uncompressed u16), for measuring how
meshflow streams recordings larger than memory (issue 40):

    python3 examples/large_recording/make_ome_zarr.py big.zarr 40      # 2.6 GB, needs numpy
    meshflow surface big.zarr --shape closed --vertices 8000 --out surf
    meshflow sample big.zarr surf

K frames of 128 x 512 x 512 voxels (1 x 1 x 2 micrometres): a turning, breathing ellipsoidal
shell with bright cells in its layer on a noisy background. Written frame by frame, one
uncompressed chunk per frame and 64-slice block, so the script itself holds one frame."""
import json, os, sys
import numpy as np

out, K = sys.argv[1], int(sys.argv[2])
Z, Y, X = 128, 512, 512
CZ = 64
os.makedirs(out, exist_ok=True)
group = {"zarr_format": 3, "node_type": "group", "attributes": {"ome": {"version": "0.5",
    "multiscales": [{"version": "0.5", "axes": [
        {"name": "t", "type": "time"},
        {"name": "z", "type": "space", "unit": "micrometer"},
        {"name": "y", "type": "space", "unit": "micrometer"},
        {"name": "x", "type": "space", "unit": "micrometer"}],
        "datasets": [{"path": "s0", "coordinateTransformations": [
            {"type": "scale", "scale": [1.0, 2.0, 1.0, 1.0]}]}]}]}}}
json.dump(group, open(os.path.join(out, "zarr.json"), "w"))
array = {"zarr_format": 3, "node_type": "array", "shape": [K, Z, Y, X], "data_type": "uint16",
    "chunk_grid": {"name": "regular", "configuration": {"chunk_shape": [1, CZ, Y, X]}},
    "chunk_key_encoding": {"name": "default", "configuration": {"separator": "/"}},
    "fill_value": 0, "codecs": [{"name": "bytes", "configuration": {"endian": "little"}}],
    "dimension_names": ["t", "z", "y", "x"]}
os.makedirs(os.path.join(out, "s0"), exist_ok=True)
json.dump(array, open(os.path.join(out, "s0", "zarr.json"), "w"))
rng = np.random.default_rng(1)
cells = rng.normal(size=(1500, 3)); cells /= np.linalg.norm(cells, axis=1, keepdims=True)
z, y, x = np.meshgrid(np.arange(Z) * 2.0, np.arange(Y) * 1.0, np.arange(X) * 1.0, indexing="ij")
for k in range(K):
    a = 0.02 * k
    c, s = np.cos(a), np.sin(a)
    px, py, pz = x - 256.0, y - 256.0, z - 128.0
    rx, ry = c * px + s * py, -s * px + c * py
    scale = 1.0 + 0.05 * np.sin(0.3 * k)
    r = np.sqrt((rx / (200 * scale)) ** 2 + (ry / 170) ** 2 + (pz / (110 / scale)) ** 2)
    layer = np.abs(r - 0.95) < 0.035
    # Cells: brighter spots in the layer, a fixed pattern on the turning shell.
    d = np.stack([rx / 200, ry / 170, pz / 110], axis=-1)[layer]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    spots = (np.sin(40 * d[:, 0]) * np.sin(40 * d[:, 1]) * np.sin(40 * d[:, 2]) > 0.2)
    volume = rng.normal(100, 40, size=(Z, Y, X))
    volume[layer] += 600 + 900 * spots
    volume = np.clip(volume, 0, 65535).astype("<u2")
    for b in range(Z // CZ):
        path = os.path.join(out, "s0", "c", str(k), str(b), "0", "0")
        os.makedirs(os.path.dirname(path), exist_ok=True)
        volume[b * CZ:(b + 1) * CZ].tofile(path)
    print(f"frame {k}", flush=True)
