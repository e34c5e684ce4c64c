"""Shared test settings."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from ea_gym.cache import CACHE_DIR_VARIABLE


@pytest.fixture(scope="session", autouse=True)
def _own_cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """The tests' cached thresholds and networks go to a temporary directory, not the user's cache (subprocesses inherit it)."""
    with pytest.MonkeyPatch.context() as patch:
        path = tmp_path_factory.mktemp("ea-gym-cache")
        patch.setenv(CACHE_DIR_VARIABLE, str(path))
        yield path
