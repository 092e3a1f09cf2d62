import pytest

from wbcbench.robots import load_robot


@pytest.fixture(scope="session")
def talos():
    return load_robot("talos")


@pytest.fixture(scope="session")
def g1():
    return load_robot("g1")
