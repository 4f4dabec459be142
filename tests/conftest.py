import numpy as np
import pytest

from ipm.prior import GuidedPrior

#: Test modules that render, generate datasets, train or fit: marked ``slow``, so that
#: ``pytest -m "not slow"`` is a quick run; plain ``pytest`` runs everything.
SLOW_MODULES = {"test_render", "test_generate", "test_nets_train", "test_refine_fit",
                "test_refine_compare", "test_bench"}


def pytest_collection_modifyitems(items):
    for item in items:
        if item.module.__name__.rpartition(".")[2] in SLOW_MODULES:
            item.add_marker(pytest.mark.slow)


@pytest.fixture(scope="session")
def sampled_params():
    """Eight yarns from the guided prior (fixed seed)."""
    return GuidedPrior().sample_many(8, seed=5)


@pytest.fixture
def rng():
    return np.random.default_rng(0)
