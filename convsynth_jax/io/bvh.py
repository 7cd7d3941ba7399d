"""BVH reader and writer for any hierarchy (3- or 6-channel joints, any Euler order, End Sites).

Convention: for a joint with position channels the local translation *is* the channel values (the
OFFSET is kept only as the rest pose); for other joints the local translation is the OFFSET. Euler
angles are read with scipy's intrinsic convention, matching BVH: channels "Zrotation Xrotation
Yrotation" mean R = Rz @ Rx @ Ry.
"""
from __future__ import annotations

import io as _io
import math
from pathlib import Path

import numpy as np

from ..errors import BVHFormatError, MissingFileError
from ..rotations import euler_deg_to_quat_np, quat_to_euler_deg_np
from ..skeleton import Motion, Skeleton
from ..utils import atomic_path

_VALID_CHANNELS = {f"{a}{k}" for a in "XYZ" for k in ("position", "rotation")}


def _parse_hierarchy(lines: list[str], path: str):
    """Parse HIERARCHY lines. Returns (skeleton, index of the MOTION line)."""
    names: list[str] = []
    parents: list[int] = []
    offsets: list[list[float]] = []
    channels: list[tuple[str, ...]] = []
    end_sites: list[tuple[int, tuple[float, float, float]]] = []
    stack: list[int] = []  # joint index per open brace; -2 marks an End Site block
    pending: int | None = None  # joint or end site whose '{' we expect next
    i = 0
    n = len(lines)
    while i < n and not lines[i].strip():
        i += 1
    if i >= n or lines[i].strip().upper() != "HIERARCHY":
        raise BVHFormatError("expected 'HIERARCHY' as the first line", path, f"line {i + 1}")
    i += 1
    while i < n:
        raw = lines[i].strip()
        lineno = i + 1
        i += 1
        if not raw:
            continue
        tok = raw.split()
        key = tok[0].upper()
        if key in ("ROOT", "JOINT"):
            if len(tok) < 2:
                raise BVHFormatError(f"{tok[0]} without a name", path, f"line {lineno}")
            if key == "ROOT" and names:
                raise BVHFormatError("only one ROOT is supported", path, f"line {lineno}")
            if key == "JOINT" and not stack:
                raise BVHFormatError("JOINT outside of any joint block", path, f"line {lineno}")
            parent = stack[-1] if stack else -1
            if parent == -2:
                raise BVHFormatError("JOINT inside an End Site", path, f"line {lineno}")
            names.append(" ".join(tok[1:]))
            parents.append(parent)
            offsets.append([0.0, 0.0, 0.0])
            channels.append(())
            pending = len(names) - 1
        elif key == "END":
            if not stack or stack[-1] < 0:
                raise BVHFormatError("End Site outside of a joint", path, f"line {lineno}")
            end_sites.append((stack[-1], (0.0, 0.0, 0.0)))
            pending = -2
        elif raw == "{":
            if pending is None:
                raise BVHFormatError("'{' without a joint before it", path, f"line {lineno}")
            stack.append(pending)
            pending = None
        elif raw == "}":
            if not stack:
                raise BVHFormatError("unbalanced '}'", path, f"line {lineno}")
            stack.pop()
        elif key == "OFFSET":
            try:
                vals = [float(v) for v in tok[1:4]]
            except ValueError:
                raise BVHFormatError(f"non-numeric OFFSET {' '.join(tok[1:])!r}", path, f"line {lineno}") from None
            if len(vals) != 3 or len(tok) != 4 or not all(math.isfinite(v) for v in vals):
                raise BVHFormatError("OFFSET needs three finite numbers", path, f"line {lineno}")
            if not stack:
                raise BVHFormatError("OFFSET outside of a joint", path, f"line {lineno}")
            if stack[-1] == -2:
                end_sites[-1] = (end_sites[-1][0], tuple(vals))
            else:
                offsets[stack[-1]] = vals
        elif key == "CHANNELS":
            if not stack or stack[-1] < 0:
                raise BVHFormatError("CHANNELS outside of a joint", path, f"line {lineno}")
            try:
                count = int(tok[1])
            except (IndexError, ValueError):
                raise BVHFormatError("CHANNELS needs a count", path, f"line {lineno}") from None
            chans = tuple(tok[2:])
            if count != len(chans):
                raise BVHFormatError(f"CHANNELS says {count} but lists {len(chans)}", path, f"line {lineno}")
            if count not in (3, 6) and not (0 < count <= 6):
                raise BVHFormatError(f"unsupported channel count {count}", path, f"line {lineno}")
            bad = [c for c in chans if c not in _VALID_CHANNELS]
            if bad:
                raise BVHFormatError(f"unknown channel name(s) {bad}", path, f"line {lineno}")
            rot = [c for c in chans if c.endswith("rotation")]
            if len(rot) not in (0, 3):
                raise BVHFormatError(f"need 0 or 3 rotation channels, got {len(rot)}", path, f"line {lineno}")
            channels[stack[-1]] = chans
        elif key == "MOTION":
            if stack:
                raise BVHFormatError("MOTION before every '{' was closed", path, f"line {lineno}")
            if not names:
                raise BVHFormatError("no ROOT joint in HIERARCHY", path, f"line {lineno}")
            skel = Skeleton(tuple(names), tuple(parents), np.asarray(offsets, dtype=np.float64),
                            tuple(channels), tuple(end_sites))
            return skel, i
        else:
            raise BVHFormatError(f"unexpected token {tok[0]!r}", path, f"line {lineno}")
    raise BVHFormatError("missing MOTION section (file truncated?)", path, f"line {n}")


def _read_header_value(lines, i, label, path):
    while i < len(lines) and not lines[i].strip():
        i += 1
    if i >= len(lines):
        raise BVHFormatError(f"missing '{label}' line (file truncated?)", path, f"line {i + 1}")
    line = lines[i].strip()
    if not line.lower().startswith(label.lower()):
        raise BVHFormatError(f"expected '{label}', found {line[:40]!r}", path, f"line {i + 1}")
    value = line[len(label):].strip()
    return value, i + 1


def nominal_fps(frame_time: float) -> float:
    """1 / frame_time, snapped to the nearest integer when the file rounded it (0.0333333 -> 30)."""
    fps = 1.0 / frame_time
    return float(round(fps)) if abs(fps - round(fps)) < 1e-3 * fps else fps


def bvh_duration(path: Path) -> float:
    """Duration from the BVH header lines (Frames, Frame Time) without parsing the data."""
    frames = frame_time = None
    with open(path, "r", errors="replace") as fh:
        for lineno, line in enumerate(fh, 1):
            low = line.strip().lower()
            if low.startswith("frames:"):
                try:
                    frames = int(line.split(":", 1)[1])
                except ValueError:
                    raise BVHFormatError("'Frames:' is not an integer", path, f"line {lineno}") from None
            elif low.startswith("frame time:"):
                try:
                    frame_time = float(line.split(":", 1)[1])
                except ValueError:
                    raise BVHFormatError("'Frame Time:' is not a number", path, f"line {lineno}") from None
                break
    if frames is None or frame_time is None or frame_time <= 0:
        raise BVHFormatError("missing MOTION header (Frames / Frame Time)", path)
    return frames / nominal_fps(frame_time)


def bvh_files(path: str | Path) -> list[Path]:
    """The BVH file ``path`` or the ``*.bvh`` files directly in the folder ``path`` (sorted): what
    the renderer and the viewer show. Raises MissingFileError for a missing path, a folder without
    BVH files or a file that is not a .bvh."""
    p = Path(path)
    if not p.exists():
        raise MissingFileError("no such BVH file or folder", p)
    if p.is_dir():
        files = sorted(q for q in p.iterdir() if q.suffix.lower() == ".bvh" and q.is_file())
        if not files:
            raise MissingFileError("folder holds no .bvh files", p)
        return files
    if p.suffix.lower() != ".bvh":
        raise MissingFileError("not a .bvh file", p)
    return [p]


def load_bvh(path: str | Path, fps: float | None = None) -> Motion:
    """Read a BVH file into a :class:`Motion`; optionally resample to ``fps`` (slerp rotations)."""
    path = Path(path)
    if not path.is_file():
        raise MissingFileError("BVH file not found", path)
    try:
        text = path.read_text()
    except (UnicodeDecodeError, OSError) as e:
        raise BVHFormatError(f"cannot read as text ({e})", path) from None
    lines = text.splitlines()
    skel, i = _parse_hierarchy(lines, str(path))
    value, i = _read_header_value(lines, i, "Frames:", str(path))
    try:
        num_frames = int(value)
    except ValueError:
        raise BVHFormatError(f"'Frames:' is not an integer: {value!r}", path, f"line {i}") from None
    if num_frames <= 0:
        raise BVHFormatError("zero frames", path, f"line {i}")
    value, i = _read_header_value(lines, i, "Frame Time:", str(path))
    try:
        frame_time = float(value)
    except ValueError:
        raise BVHFormatError(f"'Frame Time:' is not a number: {value!r}", path, f"line {i}") from None
    if not (frame_time > 0 and math.isfinite(frame_time)):
        raise BVHFormatError(f"frame time must be positive, got {frame_time}", path, f"line {i}")
    num_channels = sum(len(c) for c in skel.channels)
    data_lines = lines[i:]
    while data_lines and not data_lines[-1].strip():
        data_lines.pop()
    first_data_line = i + 1
    data = None
    if len(data_lines) == num_frames:
        try:
            flat = np.array(" ".join(data_lines).split(), dtype=np.float64)
            if flat.size == num_frames * num_channels:
                data = flat.reshape(num_frames, num_channels)
        except ValueError:
            data = None
    if data is None:  # slow path: find the first bad line and say where it is
        if len(data_lines) < num_frames:
            raise BVHFormatError(f"file truncated: header says {num_frames} frames, found {len(data_lines)}",
                                 path, f"line {first_data_line + len(data_lines)}")
        if len(data_lines) > num_frames:
            raise BVHFormatError(f"header says {num_frames} frames but {len(data_lines)} data lines follow",
                                 path, f"line {first_data_line + num_frames}")
        for f, line in enumerate(data_lines):
            toks = line.split()
            if len(toks) != num_channels:
                raise BVHFormatError(f"frame {f} has {len(toks)} values, expected {num_channels}",
                                     path, f"line {first_data_line + f}")
            for t in toks:
                try:
                    float(t)
                except ValueError:
                    raise BVHFormatError(f"frame {f}: non-numeric value {t!r}", path,
                                         f"line {first_data_line + f}") from None
        raise BVHFormatError("cannot parse motion data", path, f"line {first_data_line}")
    if not np.all(np.isfinite(data)):
        bad = np.argwhere(~np.isfinite(data))[0]
        raise BVHFormatError(f"frame {bad[0]}: non-finite value in channel {bad[1]}", path,
                             f"line {first_data_line + bad[0]}")
    motion = _channels_to_motion(skel, data, nominal_fps(frame_time), str(path))
    if fps is not None:
        motion = motion.resample(fps)
    return motion


def _channels_to_motion(skel: Skeleton, data: np.ndarray, fps: float, name: str) -> Motion:
    F = data.shape[0]
    J = skel.num_joints
    rotations = np.zeros((F, J, 4), dtype=np.float64)
    rotations[..., 0] = 1.0
    translations = np.broadcast_to(skel.offsets, (F, J, 3)).copy()
    col = 0
    by_order: dict[str, list[tuple[int, list[int]]]] = {}
    for j, chans in enumerate(skel.channels):
        rot_cols = []
        for c in chans:
            if c.endswith("position"):
                translations[:, j, "XYZ".index(c[0])] = data[:, col]
            else:
                rot_cols.append(col)
            col += 1
        if rot_cols:
            by_order.setdefault(skel.rotation_order(j), []).append((j, rot_cols))
    for order, items in by_order.items():
        joints = [j for j, _ in items]
        cols = np.array([c for _, c in items])  # (n, 3)
        angles = data[:, cols]  # (F, n, 3)
        rotations[:, joints] = euler_deg_to_quat_np(angles, order)
    return Motion(skel, rotations, translations, float(fps), name)


def _file_order(skel: Skeleton) -> list[int]:
    """Joint indices in the order the HIERARCHY lists them (depth first from the root, children in
    index order): the order of the channel columns of the file. Equal to the skeleton's order for a
    skeleton read from BVH; a skeleton built in another order (SMPL-X's) is written this way."""
    order: list[int] = []
    stack = [j for j, p in enumerate(skel.parents) if p < 0][::-1]
    while stack:
        j = stack.pop()
        order.append(j)
        stack.extend(reversed(skel.children(j)))
    return order


def motion_to_channels(motion: Motion) -> np.ndarray:
    """(F, total_channels) BVH channel values (degrees) of a motion, in the file's channel order
    (the joints as the HIERARCHY lists them, :func:`_file_order`)."""
    for name, arr in (("rotation", motion.rotations), ("translation", motion.translations)):
        bad = np.argwhere(~np.isfinite(np.asarray(arr)))
        if bad.size:
            raise BVHFormatError(f"non-finite {name} at frame {bad[0][0]}, joint {motion.skeleton.names[bad[0][1]]!r}",
                                 motion.name or None)
    skel = motion.skeleton
    F = motion.num_frames
    cols = []
    rot = np.asarray(motion.rotations, dtype=np.float64)
    trans = np.asarray(motion.translations, dtype=np.float64)
    for j in _file_order(skel):
        chans = skel.channels[j]
        if not chans:
            continue
        euler = None
        order = skel.rotation_order(j)
        if order:
            euler = quat_to_euler_deg_np(rot[:, j], order)
        k = 0
        for c in chans:
            if c.endswith("position"):
                cols.append(trans[:, j, "XYZ".index(c[0])])
            else:
                cols.append(euler[:, k])
                k += 1
    return np.stack(cols, axis=1) if cols else np.zeros((F, 0))


def _hierarchy_text(skel: Skeleton) -> str:
    out = ["HIERARCHY"]
    ends: dict[int, list] = {}
    for parent, off in skel.end_sites:
        ends.setdefault(parent, []).append(off)

    def fmt(v):
        return " ".join(f"{float(x):.6f}" for x in v)

    def emit(j, depth):
        pad = "\t" * depth
        out.append(f"{pad}{'ROOT' if skel.parents[j] < 0 else 'JOINT'} {skel.names[j]}")
        out.append(f"{pad}{{")
        out.append(f"{pad}\tOFFSET {fmt(skel.offsets[j])}")
        if skel.channels[j]:
            out.append(f"{pad}\tCHANNELS {len(skel.channels[j])} {' '.join(skel.channels[j])}")
        for c in skel.children(j):
            emit(c, depth + 1)
        for off in ends.get(j, []):
            out.append(f"{pad}\tEnd Site")
            out.append(f"{pad}\t{{")
            out.append(f"{pad}\t\tOFFSET {fmt(off)}")
            out.append(f"{pad}\t}}")
        out.append(f"{pad}}}")

    for root in (j for j, p in enumerate(skel.parents) if p < 0):
        emit(root, 0)
    return "\n".join(out) + "\n"


def save_bvh(motion: Motion, path: str | Path, precision: int = 6) -> Path:
    """Write ``motion`` as BVH (atomically: a failed write leaves no file behind)."""
    path = Path(path)
    try:
        data = motion_to_channels(motion)
    except BVHFormatError as e:
        raise BVHFormatError(f"refusing to write: {e.reason}", path) from None
    if not np.all(np.isfinite(data)):
        bad = np.argwhere(~np.isfinite(data))[0]
        raise BVHFormatError(f"refusing to write non-finite value at frame {bad[0]}, channel {bad[1]}", path)
    buf = _io.StringIO()
    buf.write(_hierarchy_text(motion.skeleton))
    buf.write("MOTION\n")
    buf.write(f"Frames: {motion.num_frames}\n")
    buf.write(f"Frame Time: {1.0 / motion.fps:.8f}\n")
    np.savetxt(buf, data, fmt=f"%.{precision}f", delimiter=" ")
    with atomic_path(path) as tmp:
        tmp.write_text(buf.getvalue())
    return path
