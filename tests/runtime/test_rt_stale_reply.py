"""The master checks the MBAP transaction id: a duplicated reply (here: the server sends its
first answer twice) is dropped and counted, and never lands in the next range's image."""
import pytest

from plcharness import Plc
from miptest.rt import COMPILERS, ModbusServer, one_task, tcp_device

PROG = one_task("""
PROGRAM MAIN
VAR a AT %IW500 : WORD; b AT %IW510 : WORD; END_VAR
VAR n : UDINT; END_VAR
n := n + 1;   (* matiec rejects a PROGRAM without statements *)
END_PROGRAM
""")

def config(port) -> str:
    """Two cyclic reads of one register each: a into %IW500, b into %IW510."""
    cfg = tcp_device(port, "modem")
    cfg.add("read", "a", device="modem", start=0, size=1, image="%IW500")
    cfg.add("read", "b", device="modem", start=10, size=1, image="%IW510")
    return cfg.text()


@pytest.mark.parametrize("compiler", COMPILERS)
def test_duplicated_reply_is_dropped_not_put_into_the_next_range(compiler, st_file, conf_file, tmp_path):
    server = ModbusServer()
    try:
        server.holding[0] = 111
        server.holding[10] = 222
        server.duplicate_replies = 1
        plc = Plc.build([st_file(PROG)], workdir=tmp_path, compiler=compiler,
                        config=conf_file(config(server.port)))
        plc.scan(1)
        assert plc["MAIN.a"] == 111
        assert plc["MAIN.b"] == 222  # before: 111, the duplicate of a's reply
        stats = plc.device_stats()["modem"]
        assert stats["dropped_replies"] == 1 and stats["errors"] == 0, stats
        plc.scan(20)
        assert (plc["MAIN.a"], plc["MAIN.b"]) == (111, 222)
        assert plc.device_stats()["modem"]["dropped_replies"] == 1
    finally:
        server.close()
