"""Fixtures; the shared helper functions are in helpers.py."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)
