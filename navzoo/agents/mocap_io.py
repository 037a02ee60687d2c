"""Readers for the motion-capture formats of ``../shared/data/mocap`` (no third-party parsers, no pickles).

- :func:`load_amp_npy`: the AMP humanoid clips of IsaacGymEnvs (``amp_humanoid_*.npy``). They are numpy
  ``.npy`` files holding a pickled dict, so they are read with :class:`RestrictedUnpickler`, which only
  builds ``collections.OrderedDict`` and plain numpy arrays and refuses every other class by name.
- :func:`parse_asf` / :func:`parse_amc`: the CMU Acclaim skeleton and motion files.
- :func:`parse_bvh`: Biovision hierarchies (the CMU BVH conversions).

Both CMU readers return a :class:`MocapClip`: a joint tree in the mocap's own y-up frame with rest
offsets in metres, one local rotation per joint and frame, and the root translation; :meth:`MocapClip.fk`
gives global joint positions and orientations. Every error names the offending file (and line).
"""

from __future__ import annotations

import importlib
import io
import pickle
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

# CMU length unit (ASF ":units length 0.45", inches / 0.45) and BVH units alike, in metres.
CMU_LENGTH_TO_M = 0.056444


class MocapFormatError(ValueError):
    """A motion-capture file is missing, unreadable or not what its format requires."""


# ---------------------------------------------------------------------------------------------------
# AMP humanoid clips: restricted unpickling
# ---------------------------------------------------------------------------------------------------


def _numpy_core_multiarray():
    for name in ("numpy._core.multiarray", "numpy.core.multiarray"):
        try:
            return importlib.import_module(name)
        except ImportError:  # pragma: no cover - depends on the numpy version
            continue
    raise ImportError("cannot import numpy's multiarray module")  # pragma: no cover


_MA = _numpy_core_multiarray()
# (module, name) -> object. ``numpy.core`` is numpy < 2's name of ``numpy._core``: files written by
# either version refer to the same few callables.
_ALLOWED_GLOBALS: dict[tuple[str, str], object] = {
    ("collections", "OrderedDict"): OrderedDict,
    ("numpy", "ndarray"): np.ndarray,
    ("numpy", "dtype"): np.dtype,
}
for _mod in ("numpy.core.multiarray", "numpy._core.multiarray"):
    _ALLOWED_GLOBALS[(_mod, "_reconstruct")] = _MA._reconstruct
    _ALLOWED_GLOBALS[(_mod, "scalar")] = _MA.scalar


class RestrictedUnpickler(pickle.Unpickler):
    """An unpickler that builds only ``OrderedDict``, ``ndarray``, ``dtype`` and numpy's reconstructors.

    Any other global a pickle refers to (``os.system``, ``builtins.eval``, a numpy object that is not
    a plain array, ...) raises :class:`pickle.UnpicklingError` naming it, before anything is called.
    """

    def find_class(self, module: str, name: str) -> object:
        obj = _ALLOWED_GLOBALS.get((module, name))
        if obj is None:
            raise pickle.UnpicklingError(
                f"refusing to unpickle global '{module}.{name}': only collections.OrderedDict and plain "
                "numpy arrays (numpy.ndarray, numpy.dtype, numpy's _reconstruct/scalar) are allowed"
            )
        return obj


def restricted_loads(data: bytes) -> object:
    """``pickle.loads`` through :class:`RestrictedUnpickler`."""
    return RestrictedUnpickler(io.BytesIO(data)).load()


def _read_npy_object(path: Path) -> object:
    """The object stored in an ``.npy`` file of dtype ``object`` (a pickle), unpickled safely."""
    try:
        with open(path, "rb") as f:
            version = np.lib.format.read_magic(f)
            if version == (1, 0):
                shape, _fortran, dtype = np.lib.format.read_array_header_1_0(f)
            elif version == (2, 0):
                shape, _fortran, dtype = np.lib.format.read_array_header_2_0(f)
            else:
                raise MocapFormatError(f"{path}: unsupported .npy format version {version}")
            payload = f.read()
    except OSError as exc:
        raise MocapFormatError(f"cannot read {path}: {exc}") from exc
    except ValueError as exc:  # bad magic string or header
        raise MocapFormatError(f"{path}: not a .npy file ({exc})") from exc
    if dtype != np.dtype(object):
        # A plain numeric array needs no unpickling at all.
        raise MocapFormatError(f"{path}: expected a pickled dict (.npy of dtype object), got dtype {dtype}")
    try:
        arr = restricted_loads(payload)
    except pickle.UnpicklingError as exc:
        raise MocapFormatError(f"{path}: {exc}") from exc
    except Exception as exc:  # truncated or corrupt pickle stream
        raise MocapFormatError(f"{path}: corrupt pickle payload ({type(exc).__name__}: {exc})") from exc
    if not isinstance(arr, np.ndarray) or arr.shape != tuple(shape):
        raise MocapFormatError(f"{path}: the pickle does not hold an array of shape {shape}")
    return arr.item() if arr.shape == () else arr


def _unwrap(x: object) -> object:
    """poselib stores tensors as ``{"arr": ndarray, "context": {...}}``: return the arrays."""
    if isinstance(x, dict):
        if "arr" in x and isinstance(x["arr"], np.ndarray):
            return x["arr"]
        return {k: _unwrap(v) for k, v in x.items()}
    return x


@dataclass(frozen=True)
class AmpMotion:
    """One AMP humanoid clip (poselib ``SkeletonMotion``), z-up.

    Attributes:
        node_names: the 15 body names (``pelvis``, ``torso``, ...).
        parent_indices: (15,) parent body of each body (-1 for the pelvis).
        local_translation: (15, 3) body origin in its parent's frame (m).
        rotation: (T, 15, 4) local body rotations (x, y, z, w); row 0 is the root's world rotation.
        root_translation: (T, 3) pelvis position (m), z up.
        fps: frames per second.
    """

    path: Path
    node_names: list[str]
    parent_indices: np.ndarray
    local_translation: np.ndarray
    rotation: np.ndarray
    root_translation: np.ndarray
    fps: float

    @property
    def n_frames(self) -> int:
        return self.rotation.shape[0]

    def fk(self) -> tuple[np.ndarray, np.ndarray]:
        """Global body positions (T, 15, 3) and rotations (T, 15, 4) (x, y, z, w)."""
        n = len(self.node_names)
        pos = np.zeros((self.n_frames, n, 3))
        rot: list[Rotation] = [None] * n  # type: ignore[list-item]
        for j in range(n):
            local = Rotation.from_quat(self.rotation[:, j])
            pj = int(self.parent_indices[j])
            if pj < 0:
                rot[j] = local
                pos[:, j] = self.root_translation
            else:
                rot[j] = rot[pj] * local
                pos[:, j] = pos[:, pj] + rot[pj].apply(np.tile(self.local_translation[j], (self.n_frames, 1)))
        return pos, np.stack([r.as_quat() for r in rot], axis=1)


def load_npy_dict(path: str | Path) -> dict:
    """The dict pickled in a poselib ``.npy`` file (``SkeletonMotion`` or ``SkeletonState``), with
    ``{"arr": ..., "context": ...}`` tensors unwrapped to arrays, through :class:`RestrictedUnpickler`."""
    path = Path(path)
    if not path.is_file():
        raise MocapFormatError(f"AMP clip not found: {path}")
    d = _read_npy_object(path)
    if not isinstance(d, dict):
        raise MocapFormatError(f"{path}: expected a dict, got {type(d).__name__}")
    return _unwrap(d)


def load_amp_npy(path: str | Path) -> AmpMotion:
    """Read an ``amp_humanoid_*.npy`` clip (a ``SkeletonMotion``) without executing pickled code."""
    path = Path(path)
    d = load_npy_dict(path)
    try:
        tree = d["skeleton_tree"]
        names = [str(s) for s in tree["node_names"]]
        parents = np.asarray(tree["parent_indices"], dtype=np.int64)
        local_t = np.asarray(tree["local_translation"], dtype=np.float64)
        rotation = np.asarray(d["rotation"], dtype=np.float64)
        root_t = np.asarray(d["root_translation"], dtype=np.float64)
        fps = float(np.asarray(d["fps"]))
    except (KeyError, TypeError, ValueError) as exc:
        raise MocapFormatError(f"{path}: missing or malformed field ({type(exc).__name__}: {exc})") from exc
    n = len(names)
    t = rotation.shape[0] if rotation.ndim == 3 else -1
    if (
        rotation.shape != (t, n, 4)
        or root_t.shape != (t, 3)
        or parents.shape != (n,)
        or local_t.shape != (n, 3)
        or t < 1
        or not fps > 0
    ):
        raise MocapFormatError(
            f"{path}: inconsistent shapes: rotation {rotation.shape}, root_translation {root_t.shape}, "
            f"{n} nodes, parent_indices {parents.shape}, local_translation {local_t.shape}, fps {fps}"
        )
    if not (np.all(np.isfinite(rotation)) and np.all(np.isfinite(root_t))):
        raise MocapFormatError(f"{path}: non-finite values in the clip")
    rotation = rotation / np.linalg.norm(rotation, axis=-1, keepdims=True)
    return AmpMotion(path, names, parents, local_t, rotation, root_t, fps)


# ---------------------------------------------------------------------------------------------------
# CMU mocap: a joint tree with rest offsets and per-frame local rotations
# ---------------------------------------------------------------------------------------------------


@dataclass
class MocapClip:
    """A skeleton animation in the mocap's own frame (y up), lengths in metres.

    Joints are BVH-style: ``offsets[j]`` is joint ``j``'s position relative to its parent in the rest
    pose (all local rotations identity), ``local_rot[:, j]`` rotates joint ``j``'s children, and the
    root sits at ``root_pos``. End sites are joints with identity rotation.

    Attributes:
        names: joint names (end sites are ``<parent>_end``).
        parents: parent index per joint (-1 for the root).
        offsets: (J, 3) rest offsets (m).
        local_rot: (T, J, 4) local rotations (x, y, z, w).
        root_pos: (T, 3) root translation (m).
        fps: frame rate.
    """

    path: Path
    names: list[str]
    parents: np.ndarray
    offsets: np.ndarray
    local_rot: np.ndarray
    root_pos: np.ndarray
    fps: float
    index: dict[str, int] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.index = {n: i for i, n in enumerate(self.names)}

    @property
    def n_frames(self) -> int:
        return self.root_pos.shape[0]

    def slice(self, start: int, stop: int | None = None) -> MocapClip:
        """The frames ``start:stop``."""
        return MocapClip(
            self.path,
            self.names,
            self.parents,
            self.offsets,
            self.local_rot[start:stop],
            self.root_pos[start:stop],
            self.fps,
        )

    def fk(self) -> tuple[np.ndarray, np.ndarray]:
        """Global joint positions (T, J, 3) and rotations (T, J, 4), in the mocap frame."""
        t, j = self.local_rot.shape[:2]
        pos = np.zeros((t, j, 3))
        mats = np.zeros((t, j, 3, 3))
        local = Rotation.from_quat(self.local_rot.reshape(-1, 4)).as_matrix().reshape(t, j, 3, 3)
        for k in range(j):
            p = int(self.parents[k])
            if p < 0:
                mats[:, k] = local[:, k]
                pos[:, k] = self.root_pos + self.offsets[k]
            else:
                mats[:, k] = mats[:, p] @ local[:, k]
                pos[:, k] = pos[:, p] + mats[:, p] @ self.offsets[k]
        quat = Rotation.from_matrix(mats.reshape(-1, 3, 3)).as_quat().reshape(t, j, 4)
        return pos, quat


def _euler(order: str, angles_deg: np.ndarray) -> np.ndarray:
    """Quaternions of intrinsic rotations applied in ``order`` (e.g. "ZYX": R = Rz Ry Rx)."""
    return Rotation.from_euler(
        order.upper(), np.asarray(angles_deg, dtype=np.float64), degrees=True
    ).as_quat()


# --- Acclaim ASF/AMC --------------------------------------------------------------------------------


@dataclass
class AsfBone:
    name: str
    direction: np.ndarray  # unit vector, rest pose, mocap frame
    length: float  # metres
    axis: np.ndarray  # degrees
    axis_order: str
    dof: list[str]


@dataclass
class AsfSkeleton:
    path: Path
    length_scale: float
    root_order: list[str]
    root_axis_order: str
    root_position: np.ndarray
    root_orientation: np.ndarray
    bones: dict[str, AsfBone]
    children: dict[str, list[str]]  # "root" -> [...]


def _read_text(path: Path, what: str) -> list[str]:
    if not path.is_file():
        raise MocapFormatError(f"{what} not found: {path}")
    try:
        return path.read_text(encoding="utf-8", errors="strict").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise MocapFormatError(f"cannot read {what} {path}: {exc}") from exc


def _floats(path: Path, lineno: int, tokens: list[str], n: int | None = None) -> np.ndarray:
    try:
        v = np.array([float(x) for x in tokens], dtype=np.float64)
    except ValueError as exc:
        raise MocapFormatError(f"{path}:{lineno}: expected numbers, got {' '.join(tokens)!r}") from exc
    if n is not None and v.size != n:
        raise MocapFormatError(f"{path}:{lineno}: expected {n} numbers, got {v.size}")
    if not np.all(np.isfinite(v)):
        raise MocapFormatError(f"{path}:{lineno}: non-finite number")
    return v


def parse_asf(path: str | Path, length_to_m: float = CMU_LENGTH_TO_M) -> AsfSkeleton:
    """Read an Acclaim skeleton file (``:units length`` ignored in favour of ``length_to_m``).

    CMU's ``length 0.45`` means (inches / 0.45); ``length_to_m`` (default 0.056444) converts to metres.
    Angles must be in degrees (``:units angle deg``), the only unit the CMU files use.
    """
    path = Path(path)
    lines = _read_text(path, "ASF skeleton")
    section = None
    bones: dict[str, AsfBone] = {}
    children: dict[str, list[str]] = {}
    root = {"order": [], "axis": "XYZ", "position": np.zeros(3), "orientation": np.zeros(3)}
    cur: dict | None = None
    angle_unit = "deg"
    for lineno, raw in enumerate(lines, 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        tok = line.split()
        if tok[0].startswith(":"):
            section = tok[0][1:].lower()
            if section == "units":
                pass
            continue
        if section == "units":
            if tok[0] == "angle" and len(tok) > 1:
                angle_unit = tok[1].lower()
        elif section == "root":
            key = tok[0].lower()
            if key == "order":
                root["order"] = [t.upper() for t in tok[1:]]
            elif key == "axis":
                root["axis"] = tok[1].upper()
            elif key == "position":
                root["position"] = _floats(path, lineno, tok[1:4], 3)
            elif key == "orientation":
                root["orientation"] = _floats(path, lineno, tok[1:4], 3)
        elif section == "bonedata":
            key = tok[0].lower()
            if key == "begin":
                cur = {"dof": [], "axis": np.zeros(3), "axis_order": "XYZ"}
            elif key == "end":
                if cur is None or not {"name", "direction", "length"} <= cur.keys():
                    raise MocapFormatError(f"{path}:{lineno}: bone without name, direction or length")
                d = cur["direction"]
                nrm = np.linalg.norm(d)
                bones[cur["name"]] = AsfBone(
                    cur["name"],
                    d / nrm if nrm > 0 else d,
                    cur["length"] * length_to_m,
                    cur["axis"],
                    cur["axis_order"],
                    cur["dof"],
                )
                cur = None
            elif cur is None:
                raise MocapFormatError(f"{path}:{lineno}: '{tok[0]}' outside a begin/end block")
            elif key == "name":
                cur["name"] = tok[1]
            elif key == "direction":
                cur["direction"] = _floats(path, lineno, tok[1:4], 3)
            elif key == "length":
                cur["length"] = float(_floats(path, lineno, tok[1:2], 1)[0])
            elif key == "axis":
                cur["axis"] = _floats(path, lineno, tok[1:4], 3)
                cur["axis_order"] = tok[4].upper() if len(tok) > 4 else "XYZ"
            elif key == "dof":
                cur["dof"] = [t.lower() for t in tok[1:]]
                bad = [d for d in cur["dof"] if d not in ("rx", "ry", "rz")]
                if bad:
                    raise MocapFormatError(f"{path}:{lineno}: unsupported degrees of freedom {bad}")
        elif section == "hierarchy":
            if tok[0].lower() in ("begin", "end"):
                continue
            children.setdefault(tok[0], []).extend(tok[1:])
    if angle_unit not in ("deg", "degree", "degrees"):
        raise MocapFormatError(f"{path}: only ':units angle deg' is supported, got {angle_unit!r}")
    if not bones or "root" not in children:
        raise MocapFormatError(f"{path}: no :bonedata or no :hierarchy rooted at 'root'")
    for parent, kids in children.items():
        for k in kids:
            if k not in bones:
                raise MocapFormatError(f"{path}: hierarchy names unknown bone {k!r}")
        if parent != "root" and parent not in bones:
            raise MocapFormatError(f"{path}: hierarchy names unknown bone {parent!r}")
    if sorted(root["order"]) != sorted(["TX", "TY", "TZ", "RX", "RY", "RZ"]):
        raise MocapFormatError(f"{path}: :root order must list TX TY TZ RX RY RZ, got {root['order']}")
    return AsfSkeleton(
        path,
        length_to_m,
        root["order"],
        root["axis"],
        root["position"] * length_to_m,
        root["orientation"],
        bones,
        children,
    )


def parse_amc(path: str | Path, skeleton: AsfSkeleton, fps: float = 120.0) -> MocapClip:
    """Read an Acclaim motion file for ``skeleton`` (CMU: 120 fps, not stored in the file).

    Bone rotations follow the Acclaim convention: a bone's local rotation is ``C M C^-1`` with ``C``
    the bone's ``axis`` rotation and ``M`` its dof rotation, both composed in the ``axis`` order
    about fixed axes (``XYZ``: x applied first, ``R = Rz Ry Rx``).
    """
    path = Path(path)
    lines = _read_text(path, "AMC motion")
    sk = skeleton
    # Joint tree: root, then every bone (node at the bone's start), then an end site per leaf bone.
    names: list[str] = ["root"]
    parents: list[int] = [-1]
    offsets: list[np.ndarray] = [np.zeros(3)]
    order: list[str] = []

    def visit(bone_parent: str, node_parent: int) -> None:
        for b in sk.children.get(bone_parent, []):
            names.append(b)
            parents.append(node_parent)
            offsets.append(
                np.zeros(3)
                if bone_parent == "root"
                else sk.bones[bone_parent].direction * sk.bones[bone_parent].length
            )
            order.append(b)
            me = len(names) - 1
            if b in sk.children:
                visit(b, me)
            else:
                names.append(f"{b}_end")
                parents.append(me)
                offsets.append(sk.bones[b].direction * sk.bones[b].length)

    visit("root", 0)
    index = {n: i for i, n in enumerate(names)}

    frames: list[dict[str, np.ndarray]] = []
    cur: dict[str, np.ndarray] | None = None
    for lineno, raw in enumerate(lines, 1):
        line = raw.strip()
        if not line or line.startswith("#") or line.startswith(":"):
            continue
        tok = line.split()
        if len(tok) == 1 and tok[0].isdigit():
            cur = {}
            frames.append(cur)
            continue
        if cur is None:
            raise MocapFormatError(f"{path}:{lineno}: data before the first frame number")
        name = tok[0]
        vals = _floats(path, lineno, tok[1:])
        if name == "root":
            if vals.size != len(sk.root_order):
                raise MocapFormatError(
                    f"{path}:{lineno}: root needs {len(sk.root_order)} values, got {vals.size}"
                )
        elif name in sk.bones:
            if vals.size != len(sk.bones[name].dof):
                raise MocapFormatError(
                    f"{path}:{lineno}: bone {name} has {len(sk.bones[name].dof)} dof, got {vals.size} values"
                )
        else:
            raise MocapFormatError(f"{path}:{lineno}: bone {name!r} is not in skeleton {sk.path.name}")
        cur[name] = vals
    if not frames:
        raise MocapFormatError(f"{path}: no frames")
    t = len(frames)
    j = len(names)
    quat = np.zeros((t, j, 4))
    quat[..., 3] = 1.0
    root_pos = np.zeros((t, 3))
    # Root.
    try:
        rv = np.stack([f["root"] for f in frames])
    except KeyError as exc:
        raise MocapFormatError(f"{path}: a frame has no root line") from exc
    ro = {c: k for k, c in enumerate(sk.root_order)}
    root_pos[:] = rv[:, [ro["TX"], ro["TY"], ro["TZ"]]] * sk.length_scale + sk.root_position
    c_root = Rotation.from_euler(sk.root_axis_order.lower(), sk.root_orientation, degrees=True)
    m_root = Rotation.from_euler(
        sk.root_axis_order.lower(), rv[:, [ro["R" + a] for a in sk.root_axis_order]], degrees=True
    )
    quat[:, 0] = (c_root * m_root * c_root.inv()).as_quat()
    # Bones.
    for b in order:
        bone = sk.bones[b]
        if not bone.dof:
            continue
        ang = np.zeros((t, 3))
        for fi, f in enumerate(frames):
            v = f.get(b)
            if v is None:
                raise MocapFormatError(f"{path}: frame {fi + 1} has no values for bone {b}")
            for k, d in enumerate(bone.dof):
                ang[fi, "xyz".index(d[1])] = v[k]
        ax_order = bone.axis_order
        c = Rotation.from_euler(ax_order.lower(), bone.axis, degrees=True)
        m = Rotation.from_euler(ax_order.lower(), ang[:, ["XYZ".index(a) for a in ax_order]], degrees=True)
        quat[:, index[b]] = (c * m * c.inv()).as_quat()
    return MocapClip(path, names, np.array(parents), np.array(offsets), quat, root_pos, float(fps))


# --- BVH ----------------------------------------------------------------------------------------------


def parse_bvh(path: str | Path, length_to_m: float = CMU_LENGTH_TO_M) -> MocapClip:
    """Read a BVH file: hierarchy, channels in any order, rotations in the channel order (degrees)."""
    path = Path(path)
    lines = _read_text(path, "BVH file")
    names: list[str] = []
    parents: list[int] = []
    offsets: list[np.ndarray] = []
    channels: list[list[str]] = []
    stack: list[int] = []
    pending: int | None = None
    i = 0
    n_lines = len(lines)

    def err(msg: str) -> MocapFormatError:
        return MocapFormatError(f"{path}:{i + 1}: {msg}")

    if not lines or lines[0].strip() != "HIERARCHY":
        raise MocapFormatError(f"{path}:1: a BVH file starts with HIERARCHY")
    i = 1
    while i < n_lines:
        tok = lines[i].split()
        if not tok:
            i += 1
            continue
        key = tok[0].upper()
        if key in ("ROOT", "JOINT"):
            if (key == "ROOT") != (not stack and not names):
                raise err("ROOT must come first and only once")
            name = tok[1] if len(tok) > 1 else f"joint{len(names)}"
            names.append(name)
            parents.append(stack[-1] if stack else -1)
            offsets.append(np.zeros(3))
            channels.append([])
            pending = len(names) - 1
        elif key == "END":
            if not stack:
                raise err("End Site outside a joint")
            names.append(f"{names[stack[-1]]}_end")
            parents.append(stack[-1])
            offsets.append(np.zeros(3))
            channels.append([])
            pending = len(names) - 1
        elif key == "{":
            if pending is None:
                raise err("'{' without a joint")
            stack.append(pending)
            pending = None
        elif key == "}":
            if not stack:
                raise err("unbalanced '}'")
            stack.pop()
        elif key == "OFFSET":
            if not stack:
                raise err("OFFSET outside a joint")
            offsets[stack[-1]] = _floats(path, i + 1, tok[1:4], 3) * length_to_m
        elif key == "CHANNELS":
            if not stack:
                raise err("CHANNELS outside a joint")
            try:
                n = int(tok[1])
            except (IndexError, ValueError) as exc:
                raise err("CHANNELS needs a count") from exc
            ch = [c.lower() for c in tok[2:]]
            if len(ch) != n or any(
                c not in ("xposition", "yposition", "zposition", "xrotation", "yrotation", "zrotation")
                for c in ch
            ):
                raise err(f"bad channel list {tok[2:]}")
            channels[stack[-1]] = ch
        elif key == "MOTION":
            break
        else:
            raise err(f"unexpected {tok[0]!r} in HIERARCHY")
        i += 1
    if stack or not names or i >= n_lines:
        raise MocapFormatError(f"{path}: incomplete HIERARCHY (no MOTION section or unbalanced braces)")
    # MOTION header.
    try:
        n_frames = int(lines[i + 1].split(":")[1])
        frame_time = float(lines[i + 2].split(":")[1])
    except (IndexError, ValueError) as exc:
        raise MocapFormatError(f"{path}:{i + 2}: expected 'Frames: N' and 'Frame Time: dt'") from exc
    if n_frames < 1 or not frame_time > 0:
        raise MocapFormatError(f"{path}:{i + 2}: bad frame count {n_frames} or frame time {frame_time}")
    n_ch = sum(len(c) for c in channels)
    body = " ".join(lines[i + 3 :]).split()
    if len(body) != n_frames * n_ch:
        raise MocapFormatError(
            f"{path}: MOTION has {len(body)} numbers, expected {n_frames} frames x {n_ch} channels"
        )
    try:
        data = np.array(body, dtype=np.float64).reshape(n_frames, n_ch)
    except ValueError as exc:
        raise MocapFormatError(f"{path}: non-numeric value in MOTION") from exc
    if not np.all(np.isfinite(data)):
        raise MocapFormatError(f"{path}: non-finite value in MOTION")
    j = len(names)
    quat = np.zeros((n_frames, j, 4))
    quat[..., 3] = 1.0
    root_pos = np.zeros((n_frames, 3))
    col = 0
    for k, ch in enumerate(channels):
        if not ch:
            continue
        cols = {c: col + m for m, c in enumerate(ch)}
        rot = [c for c in ch if c.endswith("rotation")]
        if rot:
            order = "".join(c[0].upper() for c in rot)
            quat[:, k] = _euler(order, data[:, [cols[c] for c in rot]])
        if any(c.endswith("position") for c in ch):
            if parents[k] != -1:
                raise MocapFormatError(
                    f"{path}: position channels on non-root joint {names[k]} are not supported"
                )
            root_pos = (
                np.stack(
                    [
                        data[:, cols[a + "position"]] if a + "position" in cols else np.zeros(n_frames)
                        for a in "xyz"
                    ],
                    axis=1,
                )
                * length_to_m
            )
        col += len(ch)
    return MocapClip(path, names, np.array(parents), np.array(offsets), quat, root_pos, 1.0 / frame_time)
