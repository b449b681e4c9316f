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
