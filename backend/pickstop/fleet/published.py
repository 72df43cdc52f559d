"""The published JSON schemas vendored in ``schemas/`` (VDA 5050, LIF), read as published.

Some published files hold trailing commas (not JSON); they are kept unchanged and read
leniently: a comma before a closing bracket or brace is dropped, nothing else is touched.
"""

from __future__ import annotations

import json
import re
from functools import cache
from pathlib import Path
from typing import Any

FOLDER = Path(__file__).parent / "schemas"
_TRAILING = re.compile(r",(\s*[}\]])")


def loads(text: str) -> Any:
    """JSON, tolerating trailing commas (outside strings: none of the schemas has one inside)."""
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return json.loads(_TRAILING.sub(r"\1", text))


@cache
def _read(name: str) -> str:
    return (FOLDER / name).read_text()


def schema(kind: str, version: str) -> dict[str, Any]:
    """The published schema of ``kind`` (``order``, ``state``, ``factsheet``, ...) at
    ``version`` (``"2.0.0"``...), a fresh copy."""
    return loads(_read(f"{kind}-{version}.schema.json"))
