"""The large recording of make_ome_zarr.py in the two other formats meshflow reads, to check
that NPY, TIFF and OME-Zarr give the same result (issue 40):

    python3 examples/large_recording/other_formats.py big.zarr big.npy big.tif   # numpy, tifffile

big.npy is (K, Z, Y, X) u16, written through a memory map; big.tif an ImageJ hyperstack
(TZYX, voxel 1 x 1 x 2 micrometres in its metadata), written page by page from that map. The
Zarr image is read chunk by chunk (uncompressed, as make_ome_zarr.py writes it), so memory
holds one chunk."""
import json, os, sys
import numpy as np
import tifffile

zarr, npy, tif = sys.argv[1:4]
meta = json.load(open(os.path.join(zarr, "s0", "zarr.json")))
K, Z, Y, X = meta["shape"]
_, CZ, CY, CX = meta["chunk_grid"]["configuration"]["chunk_shape"]
assert (CY, CX) == (Y, X) and meta["data_type"] == "uint16"
out = np.lib.format.open_memmap(npy, mode="w+", dtype="<u2", shape=(K, Z, Y, X))
for k in range(K):
    for b in range(Z // CZ):
        chunk = os.path.join(zarr, "s0", "c", str(k), str(b), "0", "0")
        out[k, b * CZ:(b + 1) * CZ] = np.fromfile(chunk, dtype="<u2").reshape(CZ, Y, X)
    print(f"npy frame {k}", flush=True)
out.flush()
del out
stack = np.load(npy, mmap_mode="r")
tifffile.imwrite(tif, stack, imagej=True, resolution=(1.0, 1.0),
                 metadata={"axes": "TZYX", "spacing": 2.0, "unit": "um"})
print("tif written", flush=True)
