"""Motion files in: BVH (any skeleton with recognisable joint names) and the package's `.npz`;
and out: BVH on the canonical skeleton (`save_bvh`)."""

from motion_env.io.bvh import load_bvh
from motion_env.io.bvh_write import save_bvh
from motion_env.io.load import load_motion

__all__ = ["load_bvh", "load_motion", "save_bvh"]
