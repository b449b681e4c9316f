"""The two test tiers (README.md, Makefile).

`make test` runs the quick tier (`pytest -m "not slow"`), `make check` (CI) the full tier
(`pytest -m "not large"`) and `make check-large` (CI, right after it) the large tier
(`pytest -m large`). A test belongs to the full tier only when it is marked `@pytest.mark.slow`
in its file or is listed in FULL_TIER below, each with the reason; a parametrised test listed
in SAMPLED keeps every n-th case in the quick tier (the same cases on every run: by position)
and leaves the rest to the full tier. LARGE_TIER moves the longest tests of the full tier to
make check-large, so that make check stays within its 25 minutes on 2 cores. Nothing here
skips a test: make check and make check-large together run them all.

With matiec's iec2c on PATH some 400 more tests run (skipped without it, as in CI): its
cross-checks of the translator's corpus and the programs it builds (about 30 s of CPU for a
program that holds the library: gcc -O2 on matiec's C). Their quick tier keeps a sample of the
corpus and one program of each kind; SAME_WORKER runs the tests that build the same program one
after the other, so the build cache builds it once.

Parallel runs (pytest-xdist, `--dist loadgroup`): a module whose module-scoped fixture is
expensive (it runs once per worker that gets one of the module's tests) is kept on one worker
by ONE_WORKER, and so is a module whose session fixture collects results into one file.
"""
import os

import pytest

# node id prefix -> why it waits for the full tier (the quick tier keeps its suite by other tests)
FULL_TIER = {
    "tests/translator/test_stc_cli.py::test_whole_corpus_deterministic":
        "translates the whole corpus twice; test_deterministic_output stays quick",
    "tests/st_lib/test_lib_counting.py::test_sender_counts_to_65534_then_65535":
        "65,534 records; the refusal of the 65,535th and the receiver's number space stay quick",
    "tests/st_lib/test_lib_property.py::test_unidirectional_exactly_once":
        "30 generated scenarios; the bidirectional property stays quick",
    "tests/chain/test_chain_cosim.py::test_chain_scan_tick_is_a_parameter":
        "a long run at several scan ticks",
    "tests/chain/test_chain_cosim.py::test_chain_pipelined_soak_with_restarts":
        "a soak",
    "tests/chain/test_chain_warm_restart.py::test_warm_restart_rolls_back_to_the_last_snapshot":
        "real-time processes killed and restarted; the cold case stays quick",
    "tests/chain/test_chain_programs.py::test_chain_committed_configs_load[plc/central":
        "the central configs run long; the outstation's stays quick",
    "tests/chain/test_chain_many.py::test_chain_many_full_network_of_247_stations":
        "247 stations; the four-station read-out stays quick",
    "tests/chain/test_chain_many.py::test_chain_many_exact_under_loss":
        "repeats the read-out under loss; test_chain_cosim's matrix has loss in the quick tier",
    "tests/chain/test_chain_many.py::test_chain_many_a_check_that_would_see_loss":
        "a second many-station run",
    "tests/model/test_model_runner.py::test_a_violation_after_the_sender_finished_is_found_by_the_progress_search":
        "a 2 M-state search of the bidirectional warm model; the runner's other tests stay quick",
    "tests/docs/test_docs_examples.py::test_glue_example_sends_its_data":
        "runs the guide's glue example in real time; its translation stays quick",
    "tests/st_lib/test_lib_split.py::test_matiec_compiles_each_library_alone[openplc-flags":
        "OpenPLC's flags only relax matiec's checks; the plain compiles stay quick",
    "tests/chain/test_chain_programs.py::test_chain_programs_compile_with_matiec[outstation-bidi]":
        "a matiec build each; the uni programs' builds stay quick",
    "tests/chain/test_chain_programs.py::test_chain_programs_compile_with_matiec[central-bidi]":
        "a matiec build each; the uni programs' builds stay quick",
    "tests/chain/test_chain_programs.py::test_chain_programs_compile_with_matiec[central_many]":
        "a matiec build each; the uni programs' builds stay quick",
    "tests/chain/test_chain_cosim.py::test_chain_programs_compiled_by_matiec[bidi":
        "the bidirectional programs built by matiec; the uni case stays quick",
    "tests/bench/test_bench_tools.py::test_scan_cost_against_matiec_counts_both_fb_bodies":
        "the bench pair built by matiec and run under callgrind; the stc figure "
        "(test_scan_cost_without_matiec_says_why) stays quick",
}

# node id prefix -> why it runs in make check-large instead of make check (CI runs both; each
# took over a minute of make check's py-tests under its load, cdff69c, issue 45); never a
# quick-tier test: an entry here is in the full tier too
LARGE_TIER = {
    "tests/bench/test_bench_quick.py":
        "runs every benchmark in quick mode once (156 to 278 s); test_bench_tools stays in check",
    "tests/kit/test_kit_install.py::test_example_project_installs_and_runs_outside_the_checkout":
        "a fresh venv, the kit's wheel and the example's tests (86 to 121 s)",
    "tests/kit/test_kit_install.py::test_kit_installs_from_its_source_archive":
        "a fresh venv from the source archive (54 to 73 s); the installed mip-glue stays quick",
    "tests/chain/test_chain_rtu.py::test_mip_cosim_rtu_warm_soak_loses_nothing[args1]":
        "a bidirectional soak over RTU at 9600 baud (62 to 112 s); the 19200 soak stays in check",
    "tests/independent/test_indep_blark.py::test_st_lib_has_no_blark_error":
        "blark's Earley parser over both libraries (44 s of CPU); the TwinCAT glue stays in check",
}

# the second pass under IEC semantics (PLCRT_SEMANTICS=iec, make's semantics-iec-tests): these
# run many times longer there than under matiec's values, so its quick tier leaves them out
FULL_TIER_IEC = {
    "tests/st_lib/test_lib_regress_polled_reset.py": "lossy polled transfers, minutes under IEC",
    "tests/st_lib/test_lib_regress_static_cyclic.py": "late write-done regressions",
    "tests/st_lib/test_lib_counting.py": "the counter's whole number space",
    "tests/st_lib/test_lib_interop.py::test_sender_against_note_central_session_opens_with_record_1":
        "a long session against the note central",
    "tests/st_lib/test_lib_split.py::test_matiec_compiles_each_library_alone":
        "iec2c's run does not depend on PLCRT_SEMANTICS: the default pass has it",
}

# test function (node id without the parameters) -> n, or (n, k): the cases at positions
# k, k + n, k + 2n, ... stay in the quick tier (k = 0 unless given)
SAMPLED = {
    "tests/translator/test_stc_corpus.py::test_accept": 4,
    "tests/translator/test_stc_corpus.py::test_reject": 3,
    "tests/interop/test_interop_matrix.py::test_interop_cell": 6,
    "tests/chain/test_chain_cosim.py::test_chain_matrix_exact_delivery": 4,
    # matiec's cross-checks of the corpus, about 1 s of CPU a file (iec2c, then gcc on its C);
    # the value check samples other files than the accept check (a value check accepts too)
    # (one in 6 and one in 5: make test with iec2c took 5 min 40 s to 5 min 49 s with one in
    # 4 and one in 3; make check runs every file)
    "tests/translator/test_stc_matiec.py::test_matiec_accepts": 6,
    "tests/translator/test_stc_matiec.py::test_matiec_rejects": 5,
    "tests/translator/test_stc_matiec_values.py::test_matiec_same_values": (6, 3),
    # mip-probe names each wrong setting over Modbus RTU, 1-3 s a case (about 22 s in all);
    # two stay quick (a one-based TRM, a wrong unit id), every one has its TCP twin there
    "tests/probe/test_probe_rtu.py::test_rtu_wrong_setting_is_named_in_its_first_line": 5,
}

# modules whose tests run on one worker
ONE_WORKER = (
    "tests/bench/test_bench_quick.py",     # runs `make bench` once for all its tests
    "tests/interop/test_interop_matrix.py",  # writes one results file of every cell it ran
    "tests/dist/test_dist.py",             # builds the release archive once
    "tests/chain/test_chain_warm_restart.py",
)

# group -> node id prefixes of tests (in modules not in ONE_WORKER) that must run one after the
# other on one worker: those that build the same programs with matiec (the build cache,
# runtime_shim/README.md, then builds each program once; on two workers at once both built it),
# and those that share one run directory
SAME_WORKER = {
    "matiec-chain-programs": (   # plc/outstation.st and central.st (and the bidi ones)
        "tests/chain/test_chain_programs.py::test_chain_programs_compile_with_matiec",
        "tests/chain/test_chain_cosim.py::test_chain_programs_compiled_by_matiec",
        "tests/chain/test_chain_matiec_time.py::test_chain_long_timeout_makes_no_spurious_retransmission[3000-matiec]",
        "tests/chain/test_chain_matiec_time.py::test_chain_long_timeout_makes_no_spurious_retransmission[60000-matiec]",
    ),
    "matiec-kit-example": (      # kit/example's outstation
        "tests/kit/test_kit_quick.py::test_matiec_builds_the_example_when_iec2c_is_on_path",
        "tests/kit/test_kit_quick.py::test_restarts_say_whether_retain_was_restored[matiec]",
    ),
    # not a build: `mip-view --demo` runs the demo in the one run directory build/view/demo,
    # so two of these at once read each other's files (CI saw the push chain's test read a
    # pull run's directory: no driver events)
    "view-demo-rundir": (
        "tests/view/test_view_browser.py::test_demo_in_real_time_is_followed_and_stopped_with_the_view",
        "tests/view/test_view_chain.py::test_the_real_time_chain_demo_followed_with_its_ends",
        "tests/view/test_view_chain.py::test_the_real_time_push_chain_demo_followed_with_both_drivers",
    ),
}


@pytest.fixture(scope="session")
def large_tier():
    """LARGE_TIER, for the test that holds the tiers (tests/architecture/test_arch_tiers.py):
    `import conftest` would find whichever conftest.py pytest imported under that name first."""
    return dict(LARGE_TIER)


def _group(nodeid):
    """The xdist_group of a test (node id without pytest-xdist's suffix), or None."""
    module = nodeid.split("::", 1)[0]
    if module in ONE_WORKER:
        return module
    for group, prefixes in SAME_WORKER.items():
        if nodeid.startswith(prefixes):
            return group
    return None


def pytest_configure(config):
    if config.pluginmanager.hasplugin("xdist"):
        config.pluginmanager.register(_GroupCheck(config), "mip-xdist-group-check")
    # tests that run make or the demo behave the same under `make test` as from a shell: the
    # outer make's flags (-k, -j, PYTEST_MARK=..., its "Entering directory" lines) stay out
    for k in ("MAKEFLAGS", "MFLAGS", "MAKELEVEL", "MAKEOVERRIDES"):
        os.environ.pop(k, None)


def pytest_itemcollected(item):
    # as each test is collected, so the marker is there before any modifyitems hook: the
    # pytest-xdist worker names the groups in its own (_GroupCheck sees that it did)
    group = _group(item.nodeid.split("@", 1)[0])
    if group:
        item.add_marker(pytest.mark.xdist_group(group))


@pytest.hookimpl(tryfirst=True)   # before -m / -k deselect: every collected test is seen
def pytest_collection_modifyitems(config, items):
    seen = {}
    iec = os.environ.get("PLCRT_SEMANTICS") == "iec"
    for item in items:
        nodeid = item.nodeid.split("@", 1)[0]   # without pytest-xdist's group suffix
        base = nodeid.split("[", 1)[0]
        if any(nodeid.startswith(p) for p in LARGE_TIER):
            item.add_marker(pytest.mark.large)
            item.add_marker(pytest.mark.slow)
        elif any(nodeid.startswith(p) for p in FULL_TIER) or \
                (iec and any(nodeid.startswith(p) for p in FULL_TIER_IEC)):
            item.add_marker(pytest.mark.slow)
        elif base in SAMPLED:
            i = seen.get(base, 0)
            seen[base] = i + 1
            n, k = SAMPLED[base] if isinstance(SAMPLED[base], tuple) else (SAMPLED[base], 0)
            if i % n != k:
                item.add_marker(pytest.mark.slow)
    # an entry that names no test any more would silently put its tests back into the quick
    # tier (or keep none of them there): checked for every module collected whole
    if any("::" in str(a) for a in config.args):
        return
    ids = [i.nodeid.split("@", 1)[0] for i in items]
    modules = {n.split("::", 1)[0] for n in ids}
    entries = list(FULL_TIER) + list(LARGE_TIER) + list(SAMPLED) + list(FULL_TIER_IEC) + \
        [p for prefixes in SAME_WORKER.values() for p in prefixes]
    stale = [e for e in entries
             if e.split("::", 1)[0] in modules and not any(n.startswith(e) for n in ids)]
    if stale:
        raise pytest.UsageError("tests/conftest.py: tier entries that name no test: "
                                + ", ".join(sorted(stale)))



class _GroupCheck:
    """ONE_WORKER only works when pytest-xdist's worker renames each grouped test
    (`nodeid@group`); pytest 9.2 ignores that rename (its node ids are no longer the attribute
    xdist 3.8 sets), and the grouped modules then ran on both workers: the quick bench twice at
    once, 330 s each. requirements.txt pins a pytest that works; this says so if one does not."""

    def __init__(self, config):
        self.config = config

    def pytest_xdist_node_collection_finished(self, node, ids):   # on the controller
        if self.config.getvalue("dist") != "loadgroup":
            return
        lost = [i for i in ids if "@" not in i and _group(i)]
        if lost:
            pytest.exit("tests/conftest.py: pytest-xdist did not group %s (ONE_WORKER, "
                        "SAME_WORKER); pytest and pytest-xdist as pinned in requirements.txt "
                        "group them" % lost[0], returncode=4)
