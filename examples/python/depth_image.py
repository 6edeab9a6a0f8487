#!/usr/bin/python3
"""A depth image of a blob: one primary ray per pixel through Structure.intersect, the hit
distances in a numpy array, saved as a greyscale PNG (near = bright, misses black).

    PYTHONPATH=build/python /usr/bin/python3 examples/python/depth_image.py [scene.kiln|''] [depth.png]

Without a blob it builds one from samples/wuson.obj with kiln.build.
"""
import pathlib
import struct
import sys
import tempfile
import zlib

import numpy as np

import kiln

ROOT = pathlib.Path(__file__).resolve().parents[2]
WIDTH, HEIGHT, FOV = 480, 360, 40.0


def camera_rays(bounds, width, height, fov_degrees):
    """Pinhole rays from outside the bounds, looking at their centre: (origin, directions)."""
    lo, hi = np.array(bounds[:3]), np.array(bounds[3:])
    centre, radius = (lo + hi) / 2, np.linalg.norm(hi - lo) / 2
    side = np.array([1.0, 0.3, 0.45])
    eye = centre + side / np.linalg.norm(side) * radius * 2.4
    forward = (centre - eye) / np.linalg.norm(centre - eye)
    right = np.cross(forward, [0, 1, 0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    half = np.tan(np.radians(fov_degrees) / 2)
    x = (np.arange(width) + 0.5) / width * 2 - 1
    y = 1 - (np.arange(height) + 0.5) / height * 2
    xx, yy = np.meshgrid(x * half * width / height, y * half)
    dirs = forward + xx[..., None] * right + yy[..., None] * up
    return eye.astype(np.float32), dirs.reshape(-1, 3).astype(np.float32)


def write_png(path, grey):
    """An 8-bit greyscale PNG (no imaging library needed)."""
    h, w = grey.shape
    raw = b"".join(b"\0" + row.tobytes() for row in grey.astype(np.uint8))
    chunk = lambda kind, data: (struct.pack(">I", len(data)) + kind + data +
                                struct.pack(">I", zlib.crc32(kind + data)))
    png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0)) +
           chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))
    pathlib.Path(path).write_bytes(png)


def main():
    out = sys.argv[2] if len(sys.argv) > 2 else "depth.png"
    with tempfile.TemporaryDirectory() as tmp:
        given = sys.argv[1] if len(sys.argv) > 1 and sys.argv[1] else None
        blob_path = given or pathlib.Path(tmp) / "wuson.kiln"
        if given is None:
            kiln.build(ROOT / "samples" / "wuson.obj", blob_path, accel="bvh")
        with kiln.open(blob_path) as blob:
            name = next(s["name"] for s in blob.structures
                        if "rays" in blob[s["name"]].capabilities)
            eye, dirs = camera_rays(blob.input["bounds"], WIDTH, HEIGHT, FOV)
            # One origin for every ray; directions need not be normalised (t scales with them).
            dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
            hits = blob[name].intersect(eye, dirs)
    depth = hits["t"].reshape(HEIGHT, WIDTH)
    hit = np.isfinite(depth)
    near, far = depth[hit].min(), depth[hit].max()
    grey = np.where(hit, 255 - 200 * (depth - near) / max(far - near, 1e-9), 0)
    write_png(out, np.nan_to_num(grey))
    print(f"{out}: {WIDTH}x{HEIGHT}, {hit.sum():,} of {hit.size:,} rays hit {name}, "
          f"depth {near:.3f}..{far:.3f}")


if __name__ == "__main__":
    main()
