"""Slow, obvious reference of the SMPL-X axis-angle -> BVH Euler path (``convsynth_jax.io.smplx``).

Per frame and joint: the Rodrigues rotation matrix of the axis-angle triple, written out with
``math`` (R = I + sin(t) K + (1 - cos(t)) K^2 for the unit axis's cross-product matrix K), then the
textbook decomposition of R = R_Z(a) R_X(b) R_Y(c) (BVH channels ``Zrotation Xrotation Yrotation``,
intrinsic, first channel outermost):

    R = [[ca cc - sa sb sc, -sa cb, ca sc + sa sb cc],
         [sa cc + ca sb sc,  ca cb, sa sc - ca sb cc],
         [-cb sc,            sb,    cb cc          ]]

so b = asin(R[2][1]), a = atan2(-R[0][1], R[1][1]), c = atan2(-R[2][0], R[2][2]).
Plain Python lists and loops; nothing from convsynth_jax.rotations or SciPy. Also a minimal BVH
channel reader (names, channels and values as the file writes them) so tests read the converter's
output without the project's BVH reader.
"""
from __future__ import annotations

import math
from pathlib import Path


def rodrigues(v) -> list[list[float]]:
    """3x3 rotation matrix (nested lists) of an axis-angle vector (radians)."""
    x, y, z = (float(c) for c in v)
    t = math.sqrt(x * x + y * y + z * z)
    if t < 1e-12:
        return [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    kx, ky, kz = x / t, y / t, z / t
    K = [[0.0, -kz, ky], [kz, 0.0, -kx], [-ky, kx, 0.0]]
    s, c1 = math.sin(t), 1.0 - math.cos(t)
    R = [[0.0] * 3 for _ in range(3)]
    for i in range(3):
        for j in range(3):
            k2 = sum(K[i][m] * K[m][j] for m in range(3))
            R[i][j] = (1.0 if i == j else 0.0) + s * K[i][j] + c1 * k2
    return R


def matrix_to_euler_zxy_deg(R) -> tuple[float, float, float]:
    """(Z, X, Y) angles in degrees of R = R_Z R_X R_Y (the middle angle in [-90, 90])."""
    b = math.asin(max(-1.0, min(1.0, R[2][1])))
    a = math.atan2(-R[0][1], R[1][1])
    c = math.atan2(-R[2][0], R[2][2])
    return math.degrees(a), math.degrees(b), math.degrees(c)


def euler_zxy_deg_to_matrix(a: float, b: float, c: float) -> list[list[float]]:
    """R_Z(a) R_X(b) R_Y(c) for angles in degrees (the formula of the module docstring)."""
    a, b, c = math.radians(a), math.radians(b), math.radians(c)
    ca, sa, cb, sb, cc, sc = math.cos(a), math.sin(a), math.cos(b), math.sin(b), math.cos(c), math.sin(c)
    return [[ca * cc - sa * sb * sc, -sa * cb, ca * sc + sa * sb * cc],
            [sa * cc + ca * sb * sc, ca * cb, sa * sc - ca * sb * cc],
            [-cb * sc, sb, cb * cc]]


def rotation_angle_deg(A, B) -> float:
    """The angle (degrees) of the rotation A^T B between two rotation matrices."""
    tr = sum(A[m][i] * B[m][i] for i in range(3) for m in range(3))
    return math.degrees(math.acos(max(-1.0, min(1.0, (tr - 1.0) / 2.0))))


def reference_local_matrices(poses) -> list[list[list[list[float]]]]:
    """[frame][joint] Rodrigues matrices of ``poses`` (T, 3J) axis-angle."""
    out = []
    for row in poses:
        row = [float(v) for v in row]
        out.append([rodrigues(row[3 * j:3 * j + 3]) for j in range(len(row) // 3)])
    return out


def reference_local_euler_zxy_deg(poses) -> list[list[tuple[float, float, float]]]:
    """[frame][joint] (Z, X, Y) degrees of ``poses`` (T, 3J) axis-angle."""
    return [[matrix_to_euler_zxy_deg(R) for R in frame] for frame in reference_local_matrices(poses)]


def read_bvh_channels(path: str | Path) -> tuple[list[str], list[list[str]], list[list[float]]]:
    """(joint names in file order, each joint's channel names, per-frame values) of a BVH file."""
    names, channels, rows = [], [], []
    lines = Path(path).read_text().splitlines()
    i = 0
    while i < len(lines):
        tok = lines[i].split()
        if tok and tok[0] in ("ROOT", "JOINT"):
            names.append(tok[1])
            channels.append([])
        elif tok and tok[0] == "CHANNELS":
            channels[-1] = tok[2:2 + int(tok[1])]
        elif tok and tok[0] == "MOTION":
            break
        i += 1
    for line in lines[i + 3:]:
        if line.strip():
            rows.append([float(v) for v in line.split()])
    return names, channels, rows
