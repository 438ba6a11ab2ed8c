"""Shared fixtures: where the shared folder (paper, conformance session, real data) lives."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
CONFORMANCE = SHARED / "data" / "conformance" / "clean"


@pytest.fixture(scope="session")
def conformance_dir() -> Path:
    """The independent conformance session, or skip when ../shared is not beside the repo."""
    if not (CONFORMANCE / "dataset.yaml").is_file():
        pytest.skip(f"conformance session not found at {CONFORMANCE} (../shared is absent)")
    return CONFORMANCE
