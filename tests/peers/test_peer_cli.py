"""mip-peer as a user runs it: one error line and a non-zero exit when the modem goes away."""
import socket
import subprocess
import sys
import threading

PEER = [sys.executable, "-m", "mippeer.cli"]


def _server_that_hangs_up():
    """Accepts one Modbus client, reads its first request, closes without answering."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)

    def serve():
        conn, _ = srv.accept()
        conn.recv(260)
        conn.close()
        srv.close()

    threading.Thread(target=serve, daemon=True).start()
    return srv.getsockname()[1]


def test_modem_hanging_up_gives_one_line_not_a_traceback():
    port = _server_that_hangs_up()
    p = subprocess.run(PEER + ["central", "--port", str(port), "--timeout", "5"],
                       capture_output=True, text=True, timeout=30)
    assert p.returncode == 1
    assert "Traceback" not in p.stderr
    lines = [l for l in p.stderr.splitlines() if l.strip()]
    assert len(lines) == 1 and lines[0].startswith("mip-peer: error: read at 198"), p.stderr


def test_unreachable_modem_is_one_line():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    p = subprocess.run(PEER + ["outstation", "--port", str(port), "--records", "2"],
                       capture_output=True, text=True, timeout=30)
    assert p.returncode == 1 and p.stderr.strip() == f"mip-peer: error: cannot connect to 127.0.0.1:{port}"


def test_strict_and_lenient_together_is_one_line():
    p = subprocess.run(PEER + ["central", "--port", "1", "--strict", "--lenient"],
                       capture_output=True, text=True, timeout=30)
    assert p.returncode == 2 and len(p.stderr.splitlines()) == 1
    assert p.stderr.startswith("mip-peer: error: argument --lenient: not allowed with argument --strict")


def test_record_too_big_for_the_static_block_is_one_line():
    p = subprocess.run(PEER + ["outstation", "--port", "1", "--records", "3", "--record-size",
                               "30", "--static-registers", "24"],
                       capture_output=True, text=True, timeout=30)
    assert p.returncode == 2
    assert p.stderr == "mip-peer: error: a record of 30 registers does not fit 24 static registers with 1 counter(s)\n"
