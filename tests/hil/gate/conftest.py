from __future__ import annotations

import pytest


@pytest.fixture(autouse=True)
def no_github_step_summary(monkeypatch: pytest.MonkeyPatch) -> None:
    """The gate appends to $GITHUB_STEP_SUMMARY when set: never to a real CI page from a test."""
    monkeypatch.delenv("GITHUB_STEP_SUMMARY", raising=False)
