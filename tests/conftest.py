"""Shared fixtures: small cables and scenarios used across the tests."""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.params import CableSpec


@pytest.fixture
def lv() -> CableSpec:
    """Lv et al. 2017 cable, 10 masses, light damping."""
    return CableSpec.lv2017(n_masses=10, damping=0.01)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)
