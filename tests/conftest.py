"""Shared fixtures: a bare kernel and a bare FMU platform (kernel, hrt, uORB, work queues)."""

import pytest

from board.kernel import Kernel
from firmware.platform import Platform


@pytest.fixture
def kernel():
    return Kernel("test")


@pytest.fixture
def platform(kernel):
    return Platform(kernel)
