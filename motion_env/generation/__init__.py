"""Generation: one pipeline (caption + route -> motion) and its two drivers, whole clips and the stream."""

from motion_env.generation.generator import MotionGenerator
from motion_env.generation.streaming import MotionStream
from motion_env.models.sampling import SamplingConfig

__all__ = ["MotionGenerator", "MotionStream", "SamplingConfig"]
