"""The sizing rules (probe/mipprobe/sizing.py): one implementation for docs/serial.md's table
(tests/docs/test_docs_serial.py) and the parameters mip-probe recommends from its round trips."""
import pytest

from mipprobe.sizing import (link_timeout_ms, percentile, plcrt_master, recommend, st_snippet,
                             stats_ms)


def test_percentiles_are_nearest_rank():
    xs = [i / 1000 for i in range(1, 101)]          # 1..100 ms
    assert percentile(xs, 50) == 0.050 and percentile(xs, 99) == 0.099 and percentile(xs, 100) == 0.1
    assert stats_ms(xs) == {"min": 1.0, "median": 50.0, "p99": 99.0, "max": 100.0}
    assert percentile([], 50) is None and stats_ms([]) is None


def test_the_realistic_radio_sizes_as_the_table_says():
    # deliveries of 123-register blocks on a 9600 bit/s radio with 3 stations: 0.3 .. 0.9 s
    down = [0.3 + 0.006 * i for i in range(100)]      # p99 0.894 s, max 0.894
    up = [0.25 + 0.005 * i for i in range(100)]       # p99 0.745 s
    p = recommend(down, up, [0.002, 0.004])
    assert p["read_period_ms"] == 440                 # half of 894 ms, down to 10 ms
    # 2 x (894 + 745 + 2 x 440) = 5038 -> 5100
    assert p["tTimeout_ms"] == 5100 and p["tTransferTimeout_ms"] == 25500
    assert p["uMaxRetries"] == 0 and p["uMaxRetries_finite"] == 21
    assert p["reply_timeout_ms"] == 1000 and p["line_ms"] == 0
    # over Modbus RTU: plus the line's time of docs/serial.md's table
    r = recommend(down, up, [0.002], baud=19200)
    assert r["tTimeout_ms"] == 5100 + link_timeout_ms(19200, 123) == 5100 + 1240
    assert "+ 1240 ms for the RTU line at 19200 baud 8E1" in r["why"]["tTimeout_ms"]


def test_a_fast_radio_keeps_the_floors():
    p = recommend([0.01] * 5, [0.01] * 5, [0.2])
    assert p["read_period_ms"] == 50 and p["tTimeout_ms"] == 300   # 2 x (10 + 10 + 100) -> 300
    assert p["reply_timeout_ms"] == 2000                            # 10 x 0.2 s


def test_nothing_measured_is_an_error_not_a_guess():
    with pytest.raises(ValueError, match="no round trips measured"):
        recommend([], [0.1], [])


def test_the_st_snippet_holds_the_values():
    p = recommend([0.01] * 5, [0.01] * 5, [0.001])
    text = st_snippet(p, "site A")
    assert text.splitlines()[0] == "(* site A *)"
    assert "    MIP_tTimeout : TIME := T#300ms;" in text and text.rstrip().endswith("END_VAR")


def test_the_plcrt_section_is_what_plcrt_loads(tmp_path):
    """plcrt's own --check loads the [master] section with a device of the example's kind."""
    import subprocess
    from plcharness import build_program
    from miptest.rt import TINY
    src = tmp_path / "p.st"
    src.write_text(TINY)
    exe = build_program([src], tmp_path / "out", compiler="stc").executable
    p = recommend([0.3] * 5, [0.3] * 5, [0.002])
    text = plcrt_master(p, "site A")
    assert "[master]\npolling_period = 150ms\ntimeout = 1000ms\n" in text
    cfg = tmp_path / "c.conf"
    cfg.write_text(text + "[device trm]\nhost = 127.0.0.1\nport = 15021\n")
    r = subprocess.run([str(exe), "--check", "-c", str(cfg)], capture_output=True, text=True,
                       timeout=30)
    assert r.returncode == 0, r.stderr
