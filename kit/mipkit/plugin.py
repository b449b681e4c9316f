"""The pytest plugin of the test kit (entry point pytest11 "mipkit"; docs/test-kit.md).

Fixtures:
  mip_network   a factory: mip_network(stations=1, radio="realistic", loss_down=0.1, seed=3, ...)
                returns a mipkit.Net in the test's tmp_path (closed after the test)
  mip_st_lib    the ST files of the MIP library, in the order to pass them before your own
  mip_compiler  "stc" or "matiec": --mip-compiler (stc; auto: matiec when iec2c is on PATH)

On a failing test the report gets, per network the test made, the last lines of the emulator
trace and the sequence diagram (SVG, the docs' generator) of the last virtual seconds; the
diagram's path is also a property in JUnit XML (mip_diagram). A KitError (a program that does
not compile, a config mapping an address the program does not declare, an unknown station)
fails the test with its one line instead of a traceback.
"""
from __future__ import annotations

import pytest

from .net import KitError, Net

_KEY = "_mipkit_nets"


def pytest_addoption(parser):
    g = parser.getgroup("mipkit", "MIP logger test kit")
    g.addoption("--mip-compiler", default="stc", choices=["stc", "matiec", "auto"],
                help="ST compiler for mip_network PLCs: stc (default), matiec, or auto "
                     "(matiec when iec2c is on PATH): the same tests with the reference compiler")
    g.addoption("--mip-diagram-seconds", type=float, default=6.0,
                help="virtual seconds before the end that a failure's sequence diagram shows")
    g.addoption("--mip-trace-lines", type=int, default=30,
                help="emulator trace lines in a failure's report")


@pytest.fixture
def mip_compiler(request):
    choice = request.config.getoption("--mip-compiler")
    if choice != "auto":
        return choice
    from plcharness.build import matiec_available
    return "matiec" if matiec_available() else "stc"


@pytest.fixture
def mip_st_lib():
    from mipcosim import layout as L
    return [str(L.ST_LIB / f) for f in L.LIB_FILES]


@pytest.fixture
def mip_network(request, tmp_path, mip_compiler):
    nets = []
    setattr(request.node, _KEY, nets)

    def make(stations=1, **kw):
        kw.setdefault("compiler", mip_compiler)
        net = Net(tmp_path / f"net{len(nets) + 1}", stations, **kw)
        nets.append(net)
        return net

    yield make
    for net in nets:
        net.close()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if call.excinfo is not None and call.excinfo.errisinstance(KitError):
        report.longrepr = str(call.excinfo.value)     # one line, no traceback
    if not report.failed or call.when not in ("call", "setup"):
        return
    nets = getattr(item, _KEY, [])
    cfg = item.config
    for k, net in enumerate(nets, 1):
        if net.trace_path is None:
            continue
        try:
            net.flush_trace()
            tail = net.trace_tail(cfg.getoption("--mip-trace-lines"))
            svg = net.diagram(net.workdir / "sequence-diagram.svg",
                              last_s=cfg.getoption("--mip-diagram-seconds"),
                              title=f"{item.name}: the last records")
        except Exception as e:  # noqa: BLE001 - the report must not hide the test's failure
            report.sections.append((f"mip-kit network {k}", f"no diagram: {e}"))
            continue
        report.sections.append((f"mip-kit network {k}: emulator trace (last {len(tail)} lines)",
                                "\n".join(tail)))
        if svg is not None:
            report.sections.append((f"mip-kit network {k}: sequence diagram",
                                    f"{svg}\n(full trace: {net.trace_path})"))
            for prop in (("mip_diagram", str(svg)), ("mip_trace", str(net.trace_path))):
                report.user_properties.append(prop)
                item.user_properties.append(prop)     # JUnit XML takes them from the teardown
