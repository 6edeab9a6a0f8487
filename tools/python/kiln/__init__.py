"""Kiln from Python: open .kiln blobs, query their structures with numpy arrays, build blobs.

    import kiln, numpy as np
    with kiln.open("scene.kiln") as blob:
        bvh = blob["bvh"]
        hits = bvh.intersect(origins, directions)      # structured array t, prim, u, v
        d, i = blob["kdtree"].knn(points, k=8)        # as scipy.spatial.cKDTree.query
        county = blob["pip"].locate(lon, lat)          # int64, -1 where none

Every query takes numpy arrays (converted to the dtype it needs, copied only when they are not
already C-contiguous of that dtype), releases the GIL and runs on `threads` cores (None: all).
A structure answers the queries of its capabilities (Structure.capabilities); any other raises
TypeError naming the structure and what it offers. A broken blob raises kiln.FormatError with
the one-line reason the `kiln` CLI prints.

Lifetime: blob.vertices and the other geometry arrays are read-only views of the mapped file
(no copy). They, and every Structure, hold the mapping: Blob.close() drops only the Blob's own
reference, and the file is unmapped when the last view or structure is garbage-collected.

NaN and infinite inputs never crash: a ray with a non-finite coordinate is a miss, a
non-finite query point finds nothing (knn: inf and n; locate: -1; inside: False), a box with a
NaN bound selects nothing.
"""

from ._kiln import Blob, BuildError, FormatError, Structure, build, open  # noqa: A004

__all__ = ["Blob", "BuildError", "FormatError", "Structure", "build", "open"]
