import numpy as np
import pytest

from ipm.prior import GuidedPrior


@pytest.fixture(scope="session")
def sampled_params():
    """Eight yarns from the guided prior (fixed seed)."""
    return GuidedPrior().sample_many(8, seed=5)


@pytest.fixture
def rng():
    return np.random.default_rng(0)
