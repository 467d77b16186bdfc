import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))  # tests/seed_reference.py etc.


@pytest.fixture(scope="session")
def puma_arm():
    from dualpuma.kinematics import Arm

    return Arm.puma560()


@pytest.fixture(scope="session")
def ur5_arm():
    from dualpuma.kinematics import Arm

    return Arm.load("ur5")


@pytest.fixture()
def rng():
    return np.random.default_rng(12345)


@pytest.fixture(scope="module")
def cell():
    """The seed's default cell (module-scoped: tests must not rely on a World's history)."""
    from dualpuma.model import Cell

    return Cell.default()


@pytest.fixture(scope="module")
def world(cell):
    from dualpuma.model import World

    return World(cell)
