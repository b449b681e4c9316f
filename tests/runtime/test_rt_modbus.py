"""The Modbus master seen from an ST program (docs/dev/interfaces.md §4), driven by the
harness in virtual time against a Modbus TCP server on 127.0.0.1."""
import pytest

from plcharness import Plc, PlcError
from plcharness.config import Config
from miptest.rt import COMPILERS, ModbusServer, compiler_param, one_task, trigger_range

HANDSHAKE = one_task("""
PROGRAM MAIN
VAR
  xTrig AT %QX10.0 : BOOL;
  xDone AT %IX10.0 : BOOL;
  xErr AT %IX10.1 : BOOL;
  wStatus AT %IW60 : WORD;
  wErrors AT %IW61 : WORD;
  wLen AT %QW250 : WORD;
  wOut0 AT %QW200 : WORD;
  wOut1 AT %QW201 : WORD;
  wOut2 AT %QW202 : WORD;
  wIn0 AT %IW300 : WORD;
END_VAR
VAR
  xStart : BOOL;
  nDone : UINT;
  nErr : UINT;
  wLastStatus : WORD;
END_VAR
IF xStart AND NOT xTrig THEN
  xTrig := TRUE;
  xStart := FALSE;
ELSIF xTrig AND (xDone OR xErr) THEN
  IF xDone THEN nDone := nDone + 1; ELSE nErr := nErr + 1; END_IF;
  wLastStatus := wStatus;
  xTrig := FALSE;
END_IF;
END_PROGRAM
""")

def config(port, start=10) -> str:
    """The handshake's [write block] (FC16 of wLen registers from %QW200 at `start`) and a
    cyclic [read status] of one input register."""
    cfg = Config()
    cfg.add("master", polling_period="100ms", timeout="1s")
    cfg.add("device", "modem", host="127.0.0.1", port=port, unit_id=1, errors="%IW61")
    trigger_range(cfg, "write", "block", "modem", start, "%QW200",
                  ("%QX10.0", "%IX10.0", "%IX10.1"), "%IW60", size=3, length="%QW250")
    cfg.add("read", "status", device="modem", table="input", start=5, size=1, image="%IW300",
            policy="cycle")
    return cfg.text()



@pytest.mark.parametrize("compiler", COMPILERS)
def test_st_handshake_writes_one_request_per_trigger(compiler, server, st_file, conf_file, tmp_path):
    cfg = conf_file(config(server.port))
    plc = Plc.build([st_file(HANDSHAKE)], workdir=tmp_path, compiler=compiler, config=cfg)
    plc["MAIN.wOut0"] = 11
    plc["MAIN.wOut1"] = 22
    plc["MAIN.wOut2"] = 33
    plc["MAIN.wLen"] = 2
    plc.scan(20)
    assert server.count(16) == 0          # no trigger, no write
    plc["MAIN.xStart"] = True
    plc.scan(5)
    assert plc["MAIN.nDone"] == 1
    assert plc["MAIN.nErr"] == 0
    assert server.count(16) == 1
    assert server.log[[e[0] for e in server.log].index(16)] == (16, 10, 2)  # length word
    assert server.holding[10:13] == [11, 22, 0]
    # again, all three registers
    plc["MAIN.wLen"] = 3
    plc["MAIN.xStart"] = True
    plc.scan(5)
    assert plc["MAIN.nDone"] == 2
    assert server.holding[10:13] == [11, 22, 33]


@pytest.mark.parametrize("compiler", COMPILERS)
def test_st_handshake_reports_errors_and_status(compiler, server, st_file, conf_file, tmp_path):
    cfg = conf_file(config(server.port, start=999))
    plc = Plc.build([st_file(HANDSHAKE)], workdir=tmp_path, compiler=compiler, config=cfg)
    plc["MAIN.wLen"] = 3
    plc["MAIN.xStart"] = True
    plc.scan(5)
    assert plc["MAIN.nErr"] == 1
    assert plc["MAIN.wLastStatus"] == 2      # exception: illegal data address
    assert plc["MAIN.wErrors"] == 1          # the device's error counter
    assert plc.device_stats()["modem"]["errors"] == 1


@pytest.mark.parametrize("compiler", COMPILERS)
def test_cycle_reads_run_in_virtual_time(compiler, server, st_file, conf_file, tmp_path):
    server.input[5] = 4711
    cfg = conf_file(config(server.port))
    plc = Plc.build([st_file(HANDSHAKE)], workdir=tmp_path, compiler=compiler, config=cfg)
    plc.scan()
    assert plc["MAIN.wIn0"] == 4711
    plc.scan(49)  # 500 ms of virtual time with a 100 ms polling period
    assert server.count(4) == 5


@pytest.mark.parametrize("compiler", [compiler_param("stc")])
def test_bad_config_is_one_line_naming_file_and_line(compiler, st_file, conf_file, tmp_path):
    cfg = conf_file("[device modem]\nhost = 127.0.0.1\nspeed = 9600\n", "bad.conf")
    with pytest.raises(PlcError) as ei:
        Plc.build([st_file(HANDSHAKE)], workdir=tmp_path, compiler=compiler, config=cfg)
    msg = str(ei.value)
    assert msg.startswith(f"{cfg}:3: error: unknown key 'speed'")
    assert "\n" not in msg


@pytest.mark.parametrize("compiler", [compiler_param("stc")])
def test_socketpair_seam_answers_in_lockstep(compiler, st_file, conf_file, tmp_path):
    """A peer in the same thread answers each request in the after_send hook (co-simulation)."""
    import socket
    import struct

    peer = ModbusServer()          # only its request handler is used, not its TCP listener
    peer.input[5] = 99
    ours, theirs = socket.socketpair()
    calls = []

    def answer():
        head = theirs.recv(7)
        tid, _pid, length, unit = struct.unpack(">HHHB", head)
        reply = peer._handle(theirs.recv(length - 1))
        theirs.sendall(struct.pack(">HHHB", tid, 0, len(reply) + 1, unit) + reply)
        calls.append(plc.time_ns)

    cfg = conf_file(config(1))   # the port is never used
    plc = Plc.build([st_file(HANDSHAKE)], workdir=tmp_path, compiler=compiler, config=cfg)
    with pytest.raises(PlcError, match="no device 'nosuch'"):
        plc.set_device_fd("nosuch", ours.fileno())
    plc.set_device_fd("modem", ours.fileno(), answer)
    plc["MAIN.wLen"] = 1
    plc["MAIN.wOut0"] = 5
    plc["MAIN.xStart"] = True
    plc.scan(30)
    assert plc["MAIN.nDone"] == 1
    assert peer.holding[10] == 5
    assert plc["MAIN.wIn0"] == 99
    # 3 polls of the read range (0, 100, 200 ms) and one triggered write, at scan times
    assert calls == [0, 10_000_000, 100_000_000, 200_000_000]
    peer.close()
    ours.close()
    theirs.close()
