"""Test settings shared by tests/floorvo and tests/floorsim.

Property-based tests (Hypothesis) run under the ``floorbench`` profile: a modest number of
examples and no deadline, so the suite stays well within its time on a loaded 2-core
machine; ``HYPOTHESIS_PROFILE=thorough`` runs many more. This folder is on ``sys.path``
(pytest puts a conftest's folder there), so the strategies in ``_fuzz.py`` are importable
from both test folders. Renders cache their floor tiles (floorsim.tilecache) in a temporary
folder of the session.
"""

import os

import pytest
from hypothesis import HealthCheck, settings

settings.register_profile(
    "floorbench",
    max_examples=40,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.register_profile("thorough", max_examples=2000, deadline=None)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "floorbench"))


@pytest.fixture(autouse=True, scope="session")
def _tile_cache_in_a_temporary_folder(tmp_path_factory):
    """Renders cache floor tiles (floorsim.tilecache) in a folder of this session, never the user's."""
    mp = pytest.MonkeyPatch()
    mp.setenv("FLOORSIM_CACHE", str(tmp_path_factory.mktemp("tile-cache")))
    mp.delenv("FLOORSIM_CACHE_MAX_MB", raising=False)
    yield
    mp.undo()
