"""Shared pytest configuration for the suture-engine test suite."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import settings

ROOT = Path(__file__).resolve().parent.parent
PROCEDURES = ROOT / "procedures"

# Deterministic, bounded property tests in CI; `HYPOTHESIS_PROFILE=long` for a fuzzing session.
settings.register_profile("ci", max_examples=60, deadline=None, derandomize=True)
settings.register_profile("long", max_examples=5000, deadline=None)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


@pytest.fixture
def root() -> Path:
    """The repository root."""
    return ROOT


@pytest.fixture
def procedures_dir() -> Path:
    """The folder of bundled procedures."""
    return PROCEDURES
