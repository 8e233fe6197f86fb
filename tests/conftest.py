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


def pytest_collection_modifyitems(config, items):
    """Slow tests first (whole flights, the compiled tier's build): ``make test`` runs the
    suite under pytest-xdist with ``--dist loadfile`` (each file on one worker, so a flight
    shared by a file's tests is flown once and nobody waits for it), and files whose long tests
    start first leave the many short ones to even out the end, instead of one worker finishing
    a minute-long flight alone while the other idles. A stable sort: order within stays."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)
