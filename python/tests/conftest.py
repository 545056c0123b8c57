"""Shared fixtures: the vector file, read once."""

import tomllib
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def vectors() -> dict[str, Any]:
    with (ROOT / "protocol" / "vectors.toml").open("rb") as f:
        return tomllib.load(f)
