"""The outcome class of a refused input: the exception, one line, naming the culprit and what is allowed."""
from __future__ import annotations

import pytest


def refused(call, *patterns, exc=ValueError) -> str:
    """Call ``call()``; assert it raises ``exc`` with a one-line message holding every pattern; return it."""
    with pytest.raises(exc) as info:
        call()
    msg = str(info.value)
    assert "\n" not in msg, msg  # one line
    for p in patterns:
        assert p in msg, msg
    return msg
