"""Registers the Gymnasium environments when `motion_env` is imported."""

from __future__ import annotations


def register_envs() -> None:
    """Register every `motion_env/...` id with Gymnasium (idempotent)."""
