"""`Motion`: one clip of body poses on the canonical skeleton, with save/load to `.npz` (and BVH out)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from motion_env.motion.skeleton import FPS, NUM_JOINTS
from motion_env.motion.validation import check_finite


@dataclass
class Motion:
    """A motion clip: world joint positions of the canonical 22-joint skeleton.

    Attributes:
        joints: (T, 22, 3) float32 world positions in metres, Y up, floor at y = 0.
        fps: frames per second (20 for everything the project produces).
        text: the caption, when there is one.
        waypoints: (K, 2) or (K, 3) waypoints the motion was asked to follow, if any.
        meta: free-form string metadata (source file, labels, seed, ...).
    """

    joints: np.ndarray
    fps: float = FPS
    text: str | None = None
    waypoints: np.ndarray | None = None
    meta: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        joints = np.asarray(self.joints, dtype=np.float32)
        if joints.ndim != 3 or joints.shape[1:] != (NUM_JOINTS, 3) or joints.shape[0] < 1:
            raise ValueError(
                f"Motion.joints must have shape (T, {NUM_JOINTS}, 3) with T >= 1, got {tuple(joints.shape)}"
            )
        check_finite(joints, "Motion.joints", "frames")
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise ValueError(f"Motion.fps must be a positive number, got {self.fps!r}")
        self.joints = joints
        self.fps = float(self.fps)
        if self.waypoints is not None:
            wp = np.asarray(self.waypoints, dtype=np.float32)
            if wp.ndim != 2 or wp.shape[1] not in (2, 3):
                raise ValueError(f"Motion.waypoints must have shape (K, 2) or (K, 3), got {wp.shape}")
            self.waypoints = wp
        self.meta = {str(k): str(v) for k, v in self.meta.items()}

    @property
    def num_frames(self) -> int:
        return int(self.joints.shape[0])

    @property
    def duration(self) -> float:
        """Length in seconds."""
        return self.num_frames / self.fps

    @property
    def root(self) -> np.ndarray:
        """(T, 3) pelvis positions."""
        return self.joints[:, 0]

    def save(self, path: str | Path) -> Path:
        """Write the clip to an `.npz` file (the suffix is added when missing)."""
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_suffix(path.suffix + ".npz") if path.suffix else path.with_suffix(".npz")
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = {"joints": self.joints, "fps": np.float32(self.fps)}
        if self.text is not None:
            arrays["text"] = np.array(self.text)
        if self.waypoints is not None:
            arrays["waypoints"] = self.waypoints
        arrays["meta"] = np.array(json.dumps(self.meta))
        np.savez(path, **arrays)
        return path

    def save_bvh(self, path: str | Path) -> Path:
        """Write the clip as a BVH file (``.bvh`` or ``.bvh.gz``): :func:`motion_env.io.save_bvh`."""
        from motion_env.io.bvh_write import save_bvh  # io/ is a layer above: imported on use

        return save_bvh(self, path)

    @classmethod
    def load(cls, path: str | Path) -> Motion:
        """Read a clip written by :meth:`save` (or any `.npz` with a (T, 22, 3) `joints`)."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"no motion file at {path}")
        try:
            data = np.load(path, allow_pickle=False)
        except Exception as exc:  # np.load raises several types for a corrupt file
            raise ValueError(f"{path}: not a readable .npz file ({exc})") from exc
        with data:
            if "joints" not in data:
                raise ValueError(f"{path}: no 'joints' array (keys: {sorted(data.keys())})")
            fields = {}
            for name in ("joints", "fps", "text", "waypoints", "meta"):
                if name not in data:
                    continue
                try:
                    fields[name] = data[name]
                except ValueError as exc:  # numpy's "Object arrays cannot be loaded when allow_pickle=False"
                    raise ValueError(
                        f"{path}: {name!r} is a pickled object array (Python objects, or arrays of "
                        f"different lengths, given to np.savez); a motion file holds plain arrays, and "
                        f"pickles are not loaded because loading one can run code. Save {name!r} as one "
                        f"numeric array ('joints': float, shape (T, 22, 3)), as Motion.save does"
                    ) from exc
        try:
            return cls(
                joints=fields["joints"],
                fps=_scalar(fields["fps"], "fps") if "fps" in fields else FPS,
                text=_text(fields["text"], "text") if "text" in fields else None,
                waypoints=fields.get("waypoints"),
                meta=_meta(fields["meta"]) if "meta" in fields else {},
            )
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{path}: {exc}") from exc


def _scalar(value: np.ndarray, name: str) -> float:
    if value.shape not in ((), (1,)) or value.dtype.kind not in "iuf":
        raise ValueError(f"field {name!r} must be one number, got {value.dtype} array of shape {value.shape}")
    return float(value.reshape(()))


def _text(value: np.ndarray, name: str) -> str:
    if value.shape != () or value.dtype.kind != "U":
        raise ValueError(f"field {name!r} must be one string, got {value.dtype} array of shape {value.shape}")
    return str(value)


def _meta(value: np.ndarray) -> dict[str, str]:
    try:
        meta = json.loads(_text(value, "meta"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"field 'meta' must be a JSON object of strings ({exc})") from None
    if not isinstance(meta, dict):
        raise ValueError(f"field 'meta' must be a JSON object of strings, got {type(meta).__name__}")
    return meta
