"""Shared fixtures of the bus contract tests: the fertilizer rig's contract and the foreign
(``acme``) database written from a commercial controller's point of view."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.contract.binding import Binding, load_binding
from hil.contract.quantity import Contract
from hil.contract.registry import rig_contract

DATA = Path(__file__).with_name("data")
ACME_DBC = DATA / "acme_fertilizer.dbc"
ACME_BINDING = DATA / "acme_fertilizer.binding.toml"


@pytest.fixture(scope="session")
def fert() -> Contract:
    return rig_contract("fertilizer")


@pytest.fixture(scope="session")
def acme() -> Binding:
    return load_binding(ACME_BINDING)
