"""The diagram's rows as the page shows them: docs/tools/seqdiag.py's rows (one drawing, one
reading of a trace) with the counters written as the note writes them, the repeats marked, and
the whole history cut into chunks the page keeps and scrolls.

- A trace without the PLCs' own lines (an emulator's, the demo's, the chain demo's) gets the
  labels chainsim gives its writes, from the emulator's Modbus lines: a write at the TRM's
  first write register (2001) carries a record, one at the MDP's (10) an acknowledgement
  (emulator/README.md "Register maps"; the note's logger protocol, one way up). The radio
  lines that carry such a block are then labelled by seqdiag as in the docs' pictures.
- Counters: 16#FFFF (65535) is the last record and its acknowledgement, "16#FFFF (last)";
  acknowledgement 0 is "0 (start)" (nothing accepted yet); record 0 is seqdiag's RESET record.
- An acknowledgement of 3 registers carries the echo (st_lib/PROTOCOL.md P8: [ack, 16#4D50,
  check] for acknowledgements 0 and 1): "ack 1 + echo (3 regs)". The radio's own confirmation
  of a block (a MIP ack telegram, or an answer that confirms the poll's block) is "radio ack",
  so "ack N" is always the logger's acknowledgement counter.
- A radio telegram that carries the same block again, with no write of that block by the PLC
  in between (a write of the next block may come while the modem still repeats this one), is
  the modem's own repeat (it sends a block until the link confirmed it: emulator/README.md
  "Read status" bit 4): "(modem repeat)". A write of a PLC with the same counter as its write
  before is our block writing it again: MIP_Sender's retransmission after tTimeout, or
  MIP_Receiver acknowledging a record again: "(retransmission by MIP_Sender)", "(ack written
  again)".
"""
from __future__ import annotations

import hashlib
import re

from mipcosim.kernel import MS
from mipdocs import seqdiag
from mipprobe.regmap import MDP810, TRM810

CHUNK = 100                  # rows per chunk of the history (our choice: a few screens)
FFFF = 0xFFFF
WRITE_AT = {"trm": (TRM810.write_data, "outstation", "record"),
            "mdp": (MDP810.write_data, "central", "ack")}


def counter(n):
    """A record or acknowledgement counter as the note writes it."""
    return "16#FFFF" if n == FFFF else str(n)


def with_labels(events):
    """events, plus a chainsim-style "plc" write line for every accepted block write of a side
    whose PLC wrote none itself (a trace of the emulator alone)."""
    labelled = {d.get("side") for d in events if d.get("ev") == "plc" and d.get("what") == "write"}
    out = []
    for d in events:
        out.append(d)
        if d.get("ev") != "modbus" or d.get("fc") not in (16, 23) or d.get("exc") or \
                "close" in d or d.get("ep") not in WRITE_AT:
            continue
        first, side, word = WRITE_AT[d["ep"]]
        if side in labelled or d.get("wa") != first or not isinstance(d.get("w0"), int):
            continue
        n = d.get("wq", 0)
        out.append({"t": d["t"], "ev": "plc", "side": side, "what": "write",
                    "text": f"write {word} {d['w0']} ({seqdiag.plural(n)})", "value": d["w0"],
                    "_synthetic": True})
    return out


COUNTER_RE = re.compile(r"\b(record|ack) (\d+)\b")
# the radio's confirmation of a block (MIP), told apart from the logger's acknowledgement N
RADIO_ACKS = {"ack (link confirms the block)": "radio ack: block confirmed",
              "answer, confirms the block": "answer + radio ack: block confirmed"}
ECHO_RE = re.compile(r"\back (\S+(?: \(\w+\))?) \(3 regs\)")


def _counter_words(m):
    word, n = m.group(1), int(m.group(2))
    if n == FFFF:
        return f"{word} 16#FFFF (last)"
    if n == 0 and word == "ack":
        return "ack 0 (start)"
    return m.group(0)


def note_words(text):
    """'record 65535' -> 'record 16#FFFF (last)', 'ack 0' -> 'ack 0 (start)', '[0]=65535' ->
    '[0]=16#FFFF', an acknowledgement of 3 registers 'ack 1 + echo (3 regs)'."""
    text = COUNTER_RE.sub(_counter_words, text).replace("[0]=65535", "[0]=16#FFFF")
    for radio, ours in RADIO_ACKS.items():
        text = text.replace(radio, ours)
    return ECHO_RE.sub(lambda m: f"ack {m.group(1)} + echo (3 regs)", text)


def _body(text):
    """What a block row carries, without its kind and loss: 'answer: record 2 (123 regs):
    LOST' -> 'record 2 (123 regs)'."""
    return text.split(": ", 1)[-1].removesuffix(": LOST")


def mark(rows):
    """The rows with the page's words and marks: each row's data gets "repeat": "modem",
    "block" or None."""
    out = []
    last_block = {True: None, False: None}      # down? -> the last block telegram's body
    written = {True: False, False: False}       # its PLC wrote that block again since
    last_write = {"outstation": None, "central": None}
    for t, kind, d in rows:
        d = dict(d, repeat=None)
        text = d.get("text", "")
        if kind == "mb_write" and d.get("side") in last_write:
            side = d["side"]
            if text == last_write[side] and COUNTER_RE.search(text):
                d["repeat"] = "block"
                text += (" (retransmission by MIP_Sender)" if side == "outstation"
                         else " (ack written again)")
            last_write[side] = d.get("text", "")
            # the PLC wrote the block on air again itself: what follows is not the modem's
            # repeat (a write of another block does not stop the modem repeating this one)
            if d.get("text", "").removeprefix("write ") == last_block[side == "central"]:
                written[side == "central"] = True
        elif kind == "radio" and d.get("regs"):
            down, body = d["down"], _body(text)
            if last_block[down] == body and not written[down]:
                d["repeat"] = "modem"
                text = text.replace(": LOST", "") + " (modem repeat)" + (
                    ": LOST" if d.get("lost") else "")
            last_block[down], written[down] = body, False
        d["text"] = note_words(text)
        out.append((t, kind, d))
    return out


def rows_of(events, station=1):
    """The page's rows of a trace (one station's)."""
    return mark(seqdiag.rows_from(with_labels(events), station, 0, 1 << 62))


def row_data(rows):
    return [{"t_ms": t // MS, "kind": kind, "text": d.get("text", ""),
             "lost": bool(d.get("lost")), "repeat": d.get("repeat")} for t, kind, d in rows]


class History:
    """The whole diagram, CHUNK rows an SVG: a chunk's key changes only when its rows do (the
    page fetches a chunk again only then); the SVGs of the full chunks are kept."""

    def __init__(self):
        self._svgs = {}          # key -> svg

    def update(self, rows, title):
        """[(key, first row, last row)], and the rows kept for svg()."""
        self.rows, self.title = rows, title
        chunks = []
        for i in range(0, max(len(rows), 1), CHUNK):
            part = rows[i:i + CHUNK]
            h = hashlib.sha1(repr((title, part)).encode()).hexdigest()[:16]
            chunks.append({"i": i // CHUNK, "key": h, "first": i + 1, "last": i + len(part)})
        self.chunks = chunks
        live = {c["key"] for c in chunks}
        for k in [k for k in self._svgs if k not in live]:
            del self._svgs[k]
        return chunks

    def svg(self, i):
        c = self.chunks[i]
        if c["key"] not in self._svgs:
            part = self.rows[i * CHUNK:(i + 1) * CHUNK]
            n = len(self.rows)
            title = self.title if i == 0 else f"{self.title}, rows {c['first']}–{c['last']}"
            caption = (f"Rows {c['first']}–{c['last']} of {n}; empty polls and answers and "
                       f"PLC reads without new data omitted.") if n else (
                "No rows yet; empty polls and answers and PLC reads without new data omitted.")
            self._svgs[c["key"]] = seqdiag.render(part, title, caption)
        return self._svgs[c["key"]]
