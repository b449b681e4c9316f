"""The pytest plugin of the test kit (entry point pytest11 "mipkit"; docs/test-kit.md).

Fixtures:
  mip_network   a factory: mip_network(stations=1, radio="realistic", loss_down=0.1, seed=3, ...)
                returns a mipkit.Net in the test's tmp_path (closed after the test)
  mip_st_lib    the ST files of the MIP library, in the order to pass them before your own
  mip_compiler  "stc" or "matiec": --mip-compiler (stc; auto: matiec when iec2c is on PATH)

The chain's ends are the network's: net.relay(...) (a SIPROTEC relay for your outstation),
net.unicos(...) (WinCC OA's UNICOS driver, single or a pair, for your central), net.scada(...)
(a SCADA polling your central): mipkit/ends.py, docs/test-kit.md "The chain's ends".

On a failing test the report starts with the fault (the first record that went wrong, in the
test's record numbers), the diagnosis of every MIP block in the PLCs at the fault and at the
end; sections follow with the radio and Modbus traffic around the fault, and the sequence
diagram (SVG, the docs' generator) centred on it and the trace around it (gzip) land in
--mip-results (default results/mip-kit); their paths are properties in JUnit XML
(mip_fault, mip_diagram, mip_trace). With --mip-capture SECONDS, SECONDS of the Modbus/TCP
traffic around the fault land there too, as modbus.pcapng.gz for Wireshark (property
mip_capture). After each test its network's folder (the builds, the whole trace) is removed
from tmp_path. A KitError (a program that does not compile, a config mapping an address the
program does not declare, an unknown station) fails the test with its one line instead of a
traceback.
"""
from __future__ import annotations

import pytest
from stc.semantics import SEMANTICS

from .base import KitError, KitWarning
from .net import Net

_KEY = "_mipkit_nets"


def pytest_addoption(parser):
    g = parser.getgroup("mipkit", "MIP logger test kit")
    g.addoption("--mip-compiler", default="stc", choices=["stc", "matiec", "auto"],
                help="ST compiler for mip_network PLCs: stc (default), matiec, or auto "
                     "(matiec when iec2c is on PATH): the same tests with the reference compiler")
    g.addoption("--mip-semantics", default=None, choices=SEMANTICS,
                help="stc's values where IEC 61131-3 leaves them open: matiec (the default), "
                     "openplc (OpenPLC's matiec fork), iec; default PLCRT_SEMANTICS")
    g.addoption("--mip-diagram-seconds", type=float, default=6.0,
                help="virtual seconds a failure's sequence diagram shows, centred on the fault "
                     "(default 6)")
    g.addoption("--mip-trace-lines", type=int, default=40,
                help="lines of the readable trace around the fault in a failure's report "
                     "(default 40)")
    g.addoption("--mip-capture", type=float, default=0, metavar="SECONDS",
                help="keep the Modbus/TCP traffic: a failed test leaves SECONDS virtual "
                     "seconds of it around the fault as modbus.pcapng.gz beside its diagram, for "
                     "Wireshark with the dissector mipmb.lua (default 0: off; "
                     "docs/wireshark.md)")
    g.addoption("--mip-results", default="results/mip-kit",
                help="where a failed test's sequence diagram and trace go, one folder per test "
                     "(default results/mip-kit, relative to the rootdir: the CI templates' "
                     "results/ artifact)")


@pytest.fixture
def mip_compiler(request):
    choice = request.config.getoption("--mip-compiler")
    if choice != "auto":
        return choice
    from plcharness.build import matiec_available
    return "matiec" if matiec_available() else "stc"


@pytest.fixture
def mip_st_lib():
    from mipcosim import programs as L
    return L.lib_sources()


@pytest.fixture
def mip_network(request, tmp_path, mip_compiler):
    nets = []
    setattr(request.node, _KEY, nets)

    def make(stations=1, **kw):
        kw.setdefault("compiler", mip_compiler)
        kw.setdefault("semantics", request.config.getoption("--mip-semantics"))
        kw.setdefault("capture_s", request.config.getoption("--mip-capture") or None)
        net = Net(tmp_path / f"net{len(nets) + 1}", stations, **kw)
        nets.append(net)
        return net

    yield make
    import shutil
    for net in nets:
        net.close()
        # the builds (the harness's cache keeps them) and the whole trace: megabytes per test
        # that pytest would keep for its last three runs; a failure's report has copied the
        # trace around the fault to --mip-results already (pytest_runtest_makereport)
        shutil.rmtree(net.workdir, ignore_errors=True)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if call.excinfo is not None and call.excinfo.errisinstance((KitError, KitWarning)):
        # one line, no traceback (a KitWarning raises under -W error::mipkit.KitWarning)
        report.longrepr = str(call.excinfo.value)
        return
    nets = getattr(item, _KEY, [])
    if call.when != "call" or not nets:
        return
    import re
    import shutil
    from pathlib import Path
    from .failure import failure_report
    cfg = item.config
    results = Path(cfg.getoption("--mip-results"))
    if not results.is_absolute():
        results = Path(cfg.rootpath) / results
    outdir = results / re.sub(r"[^\w.-]+", "_", item.nodeid).strip("_")
    if outdir.exists():
        shutil.rmtree(outdir, ignore_errors=True)      # an earlier run's artifacts
    if not report.failed:
        return
    message = str(call.excinfo.value) if call.excinfo is not None else ""
    heads = []
    for k, net in enumerate(nets, 1):
        if net.capture is not None:
            from .capture import save_for_report
            try:
                title, text, prop = save_for_report(net, outdir / f"net{k}", message)
                report.user_properties.append(prop)
                item.user_properties.append(prop)
            except Exception as e:  # noqa: BLE001 - the capture must not hide the failure
                title, text = "Modbus capture", f"none: {type(e).__name__}: {e}"
            report.sections.append((f"mip-kit network {k}: {title}", text))
        if net.kernel.closed:
            continue
        try:
            head, sections, props = failure_report(
                net, message, outdir / f"net{k}", cfg.getoption("--mip-diagram-seconds"),
                title=item.name, trace_lines=cfg.getoption("--mip-trace-lines"))
        except Exception as e:  # noqa: BLE001 - the report must not hide the test's failure
            report.sections.append((f"mip-kit network {k}", f"no report: {type(e).__name__}: {e}"))
            continue
        heads += head if len(nets) == 1 else [f"mip-kit: network {k}:"] + head
        for title, text in sections:
            report.sections.append((f"mip-kit network {k}: {title}", text))
        for prop in props:
            report.user_properties.append(prop)
            item.user_properties.append(prop)     # JUnit XML takes them from the teardown
    if heads:
        report.longrepr = "\n".join(heads) + "\n\n" + str(report.longrepr)
