"""The README's settings table matches service/settings.py."""

from __future__ import annotations

import re

from service.settings import Settings
from tests.paths import REPO_ROOT


def test_every_setting_is_documented_and_every_documented_one_exists() -> None:
    readme = (REPO_ROOT / "README.md").read_text()
    section = readme[readme.index("## Configuration") : readme.index("### Operating it")]
    documented = set(re.findall(r"^\| `GECKO_([A-Z0-9_]+)` \|", section, flags=re.MULTILINE))
    fields = {name.upper() for name in Settings.model_fields}
    assert fields - documented == set(), "settings missing from the README"
    assert documented - fields == set(), "the README documents settings that do not exist"
