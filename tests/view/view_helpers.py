"""What the view's tests share (a module of its own: `conftest` is a name every test folder
has)."""
import os
from pathlib import Path

import pytest

from mipview.shots import CHROMIUM  # noqa: E402   /usr/bin/chromium unless MIP_VIEW_CHROMIUM
# CI installs chromium (.ci/apt-packages.txt): there its absence fails the browser tests,
# elsewhere they skip with the package to install
needs_browser = pytest.mark.skipif(not Path(CHROMIUM).is_file() and not os.environ.get("CI"),
                                   reason="Chromium is not installed (Debian package chromium)")


def all_chunks_drawn(pg, srv):
    """Waits until the page holds every chunk of the history the server's state names (the
    page fetches the full ones after drawing the state); returns that state."""
    import json
    st = json.loads(srv.get("api/state"))
    keys = json.dumps([c["key"] for c in st["chunks"]], separators=(",", ":"))
    pg.wait_for_function(f"JSON.stringify([...document.querySelectorAll('#diagram .chunk')]"
                         f".map(d => d.dataset.key)) === {json.dumps(keys)}")
    return st
