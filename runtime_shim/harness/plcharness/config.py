"""The plcrt config file as one model: a writer (Config -> text) and a reader (text -> Config)
for the soft-PLC runtime's own format (runtime_shim/README.md, docs/wiring-plcrt.md).

The C parser (runtime_shim/src/plcrt_config.c) is the authority. The reader checks the file's
grammar the way it does and in the same order, with the same one-line errors
(FILE:LINE: error: ...): section headers and names, the keys each section knows, a key given
twice, the keys a section cannot do without. It does not check values (numbers, durations,
addresses, overlaps on the image): plcrt does when it loads the file.
tests/runtime/test_rt_config_model.py holds the two to the same grammar.

A new config key: add it to plcrt_config.c and to KEYS below (the test fails until both have it).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

# the keys of every section, in the order of plcrt_config.c's "unknown key" messages
KEYS = {
    "master": ("polling_period", "timeout", "reconnect_min", "reconnect_max"),
    "slave": ("host", "port", "idle_timeout", "byte_timeout", "watch", "watch_count"),
    "retain": ("file", "period", "request", "saved"),
    "device": ("host", "port", "serial", "baud", "parity", "data_bits", "stop_bits", "pause",
               "fc23", "unit_id", "timeout", "polling_period", "errors", "online"),
    "read": ("device", "table", "start", "size", "image", "policy", "trigger", "done", "error",
             "status", "length", "address", "status_first"),
    "write": ("device", "table", "start", "size", "image", "policy", "trigger", "done", "error",
              "status", "length", "address"),
}
NAMED = ("device", "read", "write")     # sections with a name: [device NAME]
NAME_MAX = 64                           # PLCRT_NAME_MAX (runtime_shim/src/plcrt_master.h)
_SPACE = " \t\n\r\x0b\x0c"              # C's isspace
_NAME = re.compile(r"[A-Za-z0-9_.-]+")
LOCATED = re.compile(r"%([IQM])([XBWDL])(\d+)(?:\.(\d+))?", re.I)


class ConfigError(ValueError):
    """One line: FILE:LINE: error: what is wrong (as plcrt says it)."""


@dataclass
class Section:
    """One [kind] or [kind name] section: its keys in file order (values as text, without the
    quotes mbconfig-style values may have); line and key_lines: where they are in the file
    (0 for a section made in Python)."""
    kind: str
    name: str = ""
    keys: dict = field(default_factory=dict)
    line: int = 0
    key_lines: dict = field(default_factory=dict)

    def __getitem__(self, key):
        return self.keys[key]

    def get(self, key, default=None):
        return self.keys.get(key, default)

    def text(self) -> str:
        head = f"[{self.kind} {self.name}]" if self.name else f"[{self.kind}]"
        return head + "\n" + "".join(f"{k} = {v}\n" for k, v in self.keys.items())


@dataclass
class Config:
    """A plcrt config: its sections in file order. comment: the lines before the first section
    (each written after '# ')."""
    sections: list = field(default_factory=list)
    comment: str = ""

    def add(self, kind, name="", **keys) -> Section:
        """A new section at the end; keys in the order given, None values left out (ints and
        other values are written with str()). Unknown kinds and keys are errors here, not
        only when plcrt loads the file."""
        if kind not in KEYS:
            raise ConfigError(f"unknown section [{kind}] ({', '.join(KEYS)})")
        if (kind in NAMED) != bool(name):
            raise ConfigError(f"[{kind}]: " + ("needs a name" if kind in NAMED else "takes no name"))
        for k in keys:
            if k not in KEYS[kind]:
                raise ConfigError(f"unknown key '{k}' in [{kind}] ({', '.join(KEYS[kind])})")
        sec = Section(kind, name, {k: str(v) for k, v in keys.items() if v is not None})
        self.sections.append(sec)
        return sec

    def text(self) -> str:
        """The file: the comment, then the sections with a blank line between them."""
        head = "".join(f"# {c}".rstrip() + "\n" for c in self.comment.splitlines())
        return head + "\n".join(s.text() for s in self.sections)

    def write(self, path):
        """The text into the file path; path."""
        Path(path).write_text(self.text())
        return path

    def section(self, kind, name=""):
        """The first section of that kind (and name), or None."""
        return next((s for s in self.sections if s.kind == kind and s.name == name), None)

    def of_kind(self, *kinds) -> list:
        return [s for s in self.sections if s.kind in kinds]

    @property
    def devices(self) -> list:
        return self.of_kind("device")

    @property
    def ranges(self) -> list:
        return self.of_kind("read", "write")

    def located(self):
        """(section, key, line, address, count) of every located address the config maps, in
        file order: count is the range's size for a range's image, 1 for a handshake bit or a
        word (trigger, done, error, status, length, address, unit_id = %QWn, errors, online,
        [retain] request / saved, [slave] watch / watch_count)."""
        out = []
        for s in self.sections:
            size = s.get("size", "")
            for k, v in s.keys.items():
                if LOCATED.fullmatch(v):
                    count = int(size) if k == "image" and size.isdigit() else 1
                    out.append((s, k, s.key_lines.get(k, 0), v.upper(), count))
        return out


def is_mbconfig(text) -> bool:
    """OpenPLC's mbconfig.cfg rather than plcrt's format: the runtime's own test
    (plcrt_config_is_mbconfig): the first key is Num_Devices, Polling_Period, Timeout or deviceN."""
    for raw in text.split("\n"):
        s = raw.lstrip(" \t\r")
        if not s or s.startswith("#"):
            continue
        return bool(re.match(r"Num_Devices|Polling_Period|Timeout|device\d", s))
    return False


def _unknown_key(kind, key):
    if kind in ("read", "write"):
        return (f"unknown key '{key}' in [{kind}] (device, table, start, size, image, policy, "
                f"trigger, done, error, status, length, address"
                f"{', status_first' if kind == 'read' else ''})")
    return f"unknown key '{key}' in [{kind}] ({', '.join(KEYS[kind])})"


def read(text, file="<config>") -> Config:
    """The Config of a plcrt config's text; ConfigError (FILE:LINE: error: ...) where plcrt's
    parser would stop on the file's grammar. An mbconfig.cfg is not this format (is_mbconfig)."""
    def err(line, msg):
        raise ConfigError(f"{file}:{line}: error: {msg}")

    text = text.split("\0", 1)[0]           # plcrt reads the file as a C string
    if is_mbconfig(text):
        err(1, "an OpenPLC mbconfig.cfg, not a plcrt config")
    cfg = Config()
    cur = None                              # the section the keys go to
    device = None                           # the device whose checks wait for the next device
    seen = {}                               # first line of [master], [slave], [retain]
    names = {"device": {}, "range": {}}

    def finish_range(sec):
        if sec is not None and sec.kind in ("read", "write"):
            for k in ("device", "size", "start", "image"):
                if k not in sec.keys:
                    err(sec.line, f"[{sec.kind} {sec.name}]: missing key '{k}'")

    def finish_device(sec):
        if sec is None:
            return
        kl = sec.key_lines
        if "host" in kl and "serial" in kl:
            err(kl["serial"], f"[device {sec.name}]: host and serial: a device is either Modbus "
                "TCP or RTU")
        if "host" not in kl and "serial" not in kl:
            err(sec.line, f"[device {sec.name}]: missing key 'host' (Modbus TCP) or 'serial' "
                "(Modbus RTU)")
        if "host" in kl:
            bad = [kl[k] for k in ("baud", "parity", "data_bits", "stop_bits", "pause") if k in kl]
            if bad:
                err(bad[0], "baud, parity, data_bits, stop_bits and pause are keys of serial "
                    "(RTU) devices")
        elif "port" in kl:
            err(kl["port"], "port is a key of TCP devices (this one has serial)")

    comment = []
    for lineno, raw in enumerate(text.split("\n"), 1):
        s = raw.split("#", 1)[0].strip(_SPACE)
        if not s:
            if not cfg.sections and raw.strip(_SPACE).startswith("#"):
                c = raw.strip(_SPACE)[1:]
                comment.append(c[1:] if c.startswith(" ") else c)
            continue
        if s.startswith("["):
            finish_range(cur)
            end = s.find("]")
            if end < 0 or s[end + 1:].strip(_SPACE):
                err(lineno, "section header must be [kind name]")
            inner = s[1:end].strip(_SPACE)
            m = re.match(r"([^ \t\n\r\x0b\x0c]*)[ \t\n\r\x0b\x0c]?(.*)", inner, re.S)
            kind, name = m.group(1), m.group(2).strip(_SPACE)
            if kind in ("master", "slave", "retain"):
                if name:
                    err(lineno, f"[{kind}] takes no name")
                if kind in seen:
                    err(lineno, f"[{kind}] given twice (first on line {seen[kind]})")
                seen[kind] = lineno
            elif kind in NAMED:
                if not _NAME.fullmatch(name):
                    err(lineno, f"[{kind} NAME]: name missing or not made of letters, digits, _ - .")
                if len(name.encode()) >= NAME_MAX:
                    err(lineno, "name too long")
                if kind == "device":
                    finish_device(device)
                    if name in names["device"]:
                        err(lineno, f"device '{name}' defined twice")
                else:
                    if name in names["range"]:
                        err(lineno, f"range '{name}' defined twice (line {names['range'][name]})")
            else:
                err(lineno, f"unknown section [{kind}] (master, slave, device, read, write, retain)")
            cur = Section(kind, name, line=lineno)
            cfg.sections.append(cur)
            if kind == "device":
                device = cur
                names["device"][name] = lineno
            elif kind in ("read", "write"):
                names["range"][name] = lineno
            continue
        if "=" not in s:
            err(lineno, "expected 'key = value' or [section]")
        key, val = (p.strip(_SPACE) for p in s.split("=", 1))
        if not val:
            err(lineno, f"{key}: missing value")
        if len(val) >= 2 and val[0] == '"' and val[-1] == '"':
            val = val[1:-1]
        if cur is None:
            err(lineno, f"key '{key}' outside a section ([master], [device NAME], ...)")
        if key not in KEYS[cur.kind]:
            err(lineno, _unknown_key(cur.kind, key))
        if key in cur.key_lines:
            err(lineno, f"key '{key}' given twice (first on line {cur.key_lines[key]})")
        cur.keys[key] = val
        cur.key_lines[key] = lineno
    finish_range(cur)
    finish_device(device)
    cfg.comment = "\n".join(comment)
    retain = cfg.section("retain")
    if retain is not None and "file" not in retain.keys:
        snap = "request" in retain.keys or "saved" in retain.keys
        err(retain.line, "[retain]: missing key 'file'" + (
            " (request and saved are about snapshots: they need somewhere to go)" if snap else ""))
    slave = cfg.section("slave")
    if slave is not None and ("watch" in slave.keys) != ("watch_count" in slave.keys):
        err(slave.key_lines.get("watch") or slave.key_lines["watch_count"],
            "[slave]: watch and watch_count go together (the register and its write count)")
    return cfg


def read_file(path) -> Config:
    """read() of a file, its errors named by its path."""
    return read(Path(path).read_text(errors="replace"), str(path))


_UNITS = {"ms": 10**6, "s": 10**9, "us": 10**3, "ns": 1, "": 10**6}


def duration_ns(value):
    """A plcrt duration in ns (100ms, 2s, 500us, 10ns, 1.5s; a bare number is ms, OpenPLC's
    unit), or None if it is not one."""
    m = re.fullmatch(r"\s*(\d+(?:\.\d*)?)\s*(ms|s|us|ns)?\s*", value)
    if not m:
        return None
    return int(float(m.group(1)) * _UNITS[m.group(2) or ""])
