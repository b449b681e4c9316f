"""The sequence diagrams and the throughput plot are generated from checked-in data and must be
up to date; the generators are deterministic and reject bad input with one line."""
import json

from lxml import etree
from mipcosim.trace import read_trace

from docs_helpers import REPO, refused, tool

IMG = REPO / "docs" / "img"
TRACES = REPO / "docs" / "traces"


def test_sequence_diagrams_are_up_to_date(tmp_path):
    r = tool("mkdiagrams", "--outdir", tmp_path)
    assert r.returncode == 0, r.stderr
    made = sorted(p.name for p in tmp_path.glob("seq-*.svg"))
    assert made == ["seq-bidirectional.svg", "seq-note-2-1-1.svg",
                    "seq-pipelined-slow-central.svg", "seq-pipelined.svg", "seq-restart.svg",
                    "seq-static-openplc.svg"]
    for name in made:
        assert (tmp_path / name).read_bytes() == (IMG / name).read_bytes(), \
            f"docs/img/{name} is stale: run `make docs-diagrams` and commit it"


def test_same_trace_same_bytes(tmp_path):
    for k in (1, 2):
        r = tool("seqdiag", TRACES / "note-2-1-1.jsonl", "-o", tmp_path / f"{k}.svg")
        assert r.returncode == 0, r.stderr
    assert (tmp_path / "1.svg").read_bytes() == (tmp_path / "2.svg").read_bytes()


def svg_texts(path):
    root = etree.parse(str(path)).getroot()
    assert root.tag == "{http://www.w3.org/2000/svg}svg"
    return [t.text for t in root.iter("{http://www.w3.org/2000/svg}text")]


def test_note_diagram_shows_the_lost_record_and_the_repeated_request(diagrams):
    texts = svg_texts(diagrams / "seq-note-2-1-1.svg")
    assert "answer: record 2 (123 regs): LOST" in texts
    # the central asks again with the old acknowledgement, as in the note
    assert texts.count("write ack 1 (3 regs)") >= 2   # [ack, 16#4D50, check] (P8)
    delivered = [t for t in texts if t.endswith("delivered (122 regs)") or "delivered (49" in t]
    assert delivered == ["record 1 delivered (122 regs)", "record 2 delivered (122 regs)",
                         "record 3 delivered (122 regs)", "record 4 delivered (122 regs)",
                         "record 65535 delivered (49 regs)"]
    assert "xDone: last record acknowledged" in texts


def test_restart_diagram_shows_record_1_again_and_the_receiver_error(diagrams):
    texts = svg_texts(diagrams / "seq-restart.svg")
    assert "PLC restarted" in texts
    i = texts.index("PLC restarted")
    # the restarted sender opens with record 1 at once (P6); the central reports the open
    # transfer failed and starts the new one (P18)
    assert next(t for t in texts[i:] if t.startswith("write record")) == "write record 1 (123 regs)"
    assert "xError: MIP_ERR_SENDER_RESET" in texts[i:]
    assert not any("RESET record 0" in t for t in texts)


def texts_by_row(path):
    """The texts of a diagram top to bottom (notes come first in the file, arrows after)."""
    root = etree.parse(str(path)).getroot()
    els = [(float(t.get("y")), k, t.text) for k, t in
           enumerate(root.iter("{http://www.w3.org/2000/svg}text"))]
    return [s for _, _, s in sorted(els)]


def test_pipelined_diagrams_show_the_writes_ahead_and_the_go_back(diagrams):
    texts = texts_by_row(diagrams / "seq-pipelined.svg")
    # record 4 goes up in the answer to the poll that brings acknowledgement 3 down
    i = texts.index("poll: ack 3 (1 reg)")
    assert next(t for t in texts[i:] if t.startswith("answer:")) == "answer: record 4 (123 regs)"
    assert texts.index("write record 4 (123 regs), before ack 3") < i
    assert "write record 2 (123 regs)" in texts and "write record 65535 (123 regs)" in texts
    texts = texts_by_row(diagrams / "seq-pipelined-slow-central.svg")
    assert texts.index("record 5 ignored: not the next one (4)") < texts.index(
        "no ack within tTimeout: back to record 4, window closed")
    i = texts.index("no ack within tTimeout: back to record 4, window closed")
    writes = [t for t in texts[i:] if t.startswith("write record")]
    assert writes == ["write record 4 (123 regs)", "write record 5 (123 regs)",
                      "write record 65535 (123 regs)"]


def test_a_trace_line_that_is_not_json_is_reported_with_its_line(tmp_path):
    bad = tmp_path / "t.jsonl"
    bad.write_text('{"t":0,"seq":0,"ev":"modbus"}\nnot json\n')
    r = refused("seqdiag", bad, "-o", tmp_path / "o.svg")
    assert r.stderr.startswith(f"{bad}:2:1: error: not a JSON line")
    assert "Traceback" not in r.stderr


def test_an_emulator_server_trace_renders(tmp_path):
    """A trace without the chain's "plc" lines (as mip-emulator --trace writes it) still gives
    a diagram: writes labelled by their first register, blocks by r0."""
    lines = read_trace(TRACES / "note-2-1-1.jsonl")
    plain = tmp_path / "server.jsonl"
    plain.write_text("".join(json.dumps(d) + "\n" for d in lines if d["ev"] != "plc"))
    r = tool("seqdiag", plain, "-o", tmp_path / "o.svg")
    assert r.returncode == 0, r.stderr
    texts = svg_texts(tmp_path / "o.svg")
    assert "FC16 write, [0]=2 (123 regs)" in texts
    assert "answer: [0]=2 (123 regs): LOST" in texts


def test_throughput_plot_is_up_to_date(tmp_path):
    r = tool("lossplot", REPO / "docs" / "data" / "throughput-vs-loss.json", "-o",
             tmp_path / "p.svg")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "p.svg").read_bytes() == (IMG / "throughput-vs-loss.svg").read_bytes(), \
        "docs/img/throughput-vs-loss.svg is stale: run `make docs-plot` and commit it"


def test_plot_rejects_a_file_that_is_not_throughput_data(tmp_path):
    bad = tmp_path / "d.json"
    bad.write_text('{"series": {"x": [{"loss": "a lot"}]}}')
    r = refused("lossplot", bad, "-o", tmp_path / "p.svg")
    assert r.stderr.startswith(f"lossplot: error: {bad}: not a throughput data file")
    assert len(r.stderr.strip().splitlines()) == 1


def test_a_trace_line_with_a_bad_time_is_reported(tmp_path):
    bad = tmp_path / "t.jsonl"
    bad.write_text('{"t":"soon","seq":0,"ev":"radio"}\n')
    r = refused("seqdiag", bad, "-o", tmp_path / "o.svg")
    assert r.stderr.strip() == f'{bad}:1:1: error: "t" must be a non-negative integer (ns)'
