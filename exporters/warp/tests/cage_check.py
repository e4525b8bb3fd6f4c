"""Independent checks of `frond-warp cage build` and `cage coords` output with shapely (GEOS) and
numpy: nothing here uses frond's code.

usage: cage_check.py CAGE_JSON MATTE_RAW WIDTH HEIGHT COORDS_JSON
  MATTE_RAW: the layer's matte, WIDTH*HEIGHT bytes (>= 128 is vegetation), hole-free parts.
  COORDS_JSON: `frond-warp cage coords --id <first crown>` of some points.
"""
import json
import math
import sys

import numpy as np
import shapely
from shapely.geometry import LinearRing, Polygon, box
from shapely.ops import unary_union

cage_path, matte_path, w, h, coords_path = sys.argv[1:6]
w, h = int(w), int(h)
tree = json.load(open(cage_path))
assert tree["version"] == 1 and tree["size"] == [w, h], tree["size"]
cages = {c["id"]: c for c in tree["cages"]}
polys = {i: Polygon(c["vertices"]) for i, c in cages.items()}

# Every cage: a valid simple polygon, counter-clockwise as shapely defines it, inside the picture.
picture = box(0, 0, w, h)
for i, c in cages.items():
    assert polys[i].is_valid, f"cage {i}: {shapely.is_valid_reason(polys[i])}"
    assert LinearRing(c["vertices"]).is_ccw, f"cage {i} is not counter-clockwise"
    assert picture.buffer(1e-9).contains(polys[i]), f"cage {i} leaves the picture"
    kids = [j for j, d in cages.items() if d["parent"] == i]
    assert (c["kind"] == "internal") == bool(kids), f"cage {i}: kind {c['kind']} with {len(kids)} children"
    if c["parent"] is not None:
        parent = polys[c["parent"]]
        assert parent.buffer(1.0).contains(polys[i]), f"cage {i} leaves its parent {c['parent']}"

# Crowns against the matte: the union of its vegetation pixels' squares, part by part.
matte = np.frombuffer(open(matte_path, "rb").read(), dtype=np.uint8).reshape(h, w) >= 128
pixels = unary_union([box(x, y, x + 1, y + 1) for y, x in zip(*np.nonzero(matte))])
parts = list(pixels.geoms) if pixels.geom_type == "MultiPolygon" else [pixels]
parts = [p for p in parts if p.area >= max(16, 0.02 * pixels.area)]
roots = [i for i, c in cages.items() if c["parent"] is None]
assert len(roots) == len(parts), f"{len(roots)} crowns for {len(parts)} parts"
worst_iou = 1.0
for part in parts:
    crown = max(roots, key=lambda i: polys[i].intersection(part).area)
    iou = polys[crown].intersection(part).area / polys[crown].union(part).area
    worst_iou = min(worst_iou, iou)
    assert iou > 0.97, f"crown {crown} against its part: IoU {iou:.3f}"

# Lobes: the children of an internal cage cover most of it and overlap each other little.
for i, c in cages.items():
    kids = [polys[j] for j, d in cages.items() if d["parent"] == i]
    if not kids:
        continue
    union = unary_union(kids)
    cover = union.area / polys[i].area
    overlap = (sum(k.area for k in kids) - union.area) / polys[i].area
    assert cover > 0.85 and overlap < 0.05, f"cage {i}: lobes cover {cover:.2f}, overlap {overlap:.3f}"


# Mean value coordinates: Floater's definition from angles, a second implementation.
def floater(v, x):
    v = np.asarray(v, dtype=float)
    s = v - x
    r = np.hypot(s[:, 0], s[:, 1])
    k = int(np.argmin(r))
    if r[k] < 1e-9:
        out = np.zeros(len(v))
        out[k] = 1.0
        return out
    ang = np.arctan2(s[:, 1], s[:, 0])
    alpha = np.angle(np.exp(1j * (np.roll(ang, -1) - ang)))  # angle v_i -> v_{i+1}, in (-pi, pi]
    for i in range(len(v)):  # on an edge: linear
        if abs(abs(alpha[i]) - math.pi) < 1e-9:
            out = np.zeros(len(v))
            j = (i + 1) % len(v)
            out[i], out[j] = r[j] / (r[i] + r[j]), r[i] / (r[i] + r[j])
            return out
    t = np.tan(alpha / 2)
    wts = (np.roll(t, 1) + t) / r
    return wts / wts.sum()


coords = json.load(open(coords_path))
verts = cages[coords["cage"]]["vertices"]
assert coords["vertices"] == len(verts)
worst = 0.0
for row in coords["points"]:
    x = np.asarray(row["at"], dtype=float)
    wts = np.asarray(row["weights"])
    assert abs(wts.sum() - 1) < 1e-9, wts.sum()
    assert np.allclose(wts @ np.asarray(verts), x, atol=1e-7), (wts @ np.asarray(verts), x)
    want = floater(verts, x)
    worst = max(worst, float(np.abs(wts - want).max()))
    assert row["inside"] == Polygon(verts).contains(shapely.Point(x)) or Polygon(verts).boundary.distance(
        shapely.Point(x)
    ) < 1e-9, row["at"]
assert worst < 1e-9, f"MVC differ from Floater's by {worst}"
print(
    f"ok: {len(cages)} cages valid and counter-clockwise (shapely), crowns IoU >= {worst_iou:.3f} "
    f"with the matte, {len(coords['points'])} MVC rows equal Floater's within {worst:.1e}"
)
