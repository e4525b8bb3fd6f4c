"""frond's rotation convention, written from its documentation for the tests' Python checks
(independent of frond's Rust code): the stem grows along +Y; a joint's rotation relative to its
parent is R = R_yaw(Z) R_pitch(X) R_roll(Y), angles in degrees; joints chain root to top."""

import math


def mat_mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def mat_vec(m, v):
    return [sum(m[i][k] * v[k] for k in range(3)) for i in range(3)]


def joint_matrix(pitch, yaw, roll):
    p, y, r = (math.radians(a) for a in (pitch, yaw, roll))
    rx = [[1, 0, 0], [0, math.cos(p), -math.sin(p)], [0, math.sin(p), math.cos(p)]]
    rz = [[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]]
    ry = [[math.cos(r), 0, math.sin(r)], [0, 1, 0], [-math.sin(r), 0, math.cos(r)]]
    return mat_mul(mat_mul(rz, rx), ry)


def fk(joints, heights):
    """World positions (Y up) of the points at `heights` (joint heights, optionally the top)
    for the joint angles `joints` (4 x [pitch, yaw, roll])."""
    points = [[0.0, heights[0], 0.0]]
    acc = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
    for j in range(len(heights) - 1):
        acc = mat_mul(acc, joint_matrix(*joints[j]))
        seg = mat_vec(acc, [0.0, heights[j + 1] - heights[j], 0.0])
        points.append([points[-1][i] + seg[i] for i in range(3)])
    return points


def to_blender(p):
    """Y-up (frond, glTF, BVH, USD) to Blender's Z-up world, as its importers convert."""
    return (p[0], -p[2], p[1])
