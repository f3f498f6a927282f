"""The studies layer: many designs of one problem, on an injected runner (serial, process pool)."""

from __future__ import annotations

from .runners import PointResult, ProcessRunner, Runner, SerialRunner, StudyTask, batched, run

__all__ = ["PointResult", "ProcessRunner", "Runner", "SerialRunner", "StudyTask", "batched", "run"]
