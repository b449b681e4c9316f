"""tests/view: mip-view (view/) in Debian's Chromium through Playwright, and its parts without
a browser. The PLCs of the docs' chain are built in a directory of the test process (as
tests/docs does: two workers building in build/docs/plc would remove each other's builds)."""
import shutil
from pathlib import Path

import pytest

from view_helpers import CHROMIUM

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def view_workdir(tmp_path_factory):
    d = tmp_path_factory.mktemp("view-work")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("MIP_DOCS_WORKDIR", str(d))
        yield d


@pytest.fixture(scope="session")
def browser():
    from playwright.sync_api import sync_playwright
    from mipview.shots import launch
    assert shutil.which(CHROMIUM) or Path(CHROMIUM).is_file(), f"{CHROMIUM} missing"
    with sync_playwright() as pw:
        b = launch(pw)
        yield b
        b.close()
