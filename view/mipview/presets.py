"""The runs the page offers: make run's demo, a clean transfer and the exercises' runs
(docs/exercises.md), each as docs/tools/mipsim.py would run it."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Preset:
    """A run of docs/tools/mipsim.py's kind: the options of one exercise (docs/exercises.md)."""
    title: str
    exercise: str
    records: int = 5
    polled: bool = False
    loss_up: float = 0.0
    loss_down: float = 0.0
    burst: float = 0.0
    seed: int = 1
    timeout_ms: int = 2000
    restart: str | None = None            # "outstation" / "central": a cold restart ...
    restart_at_ms: int = 1000             # ... at this virtual time
    lose_record: int = 0                  # the first uplink telegram carrying this record is
                                          # lost (mip-emulator --lose-record; not in mipsim)

    def mipsim_args(self) -> str:
        """The mipsim command line of the same run (the exercise's own command); a scripted
        lost record, which mipsim has not, is said in words."""
        out = [f"--records {self.records}"]
        out += ["--polled"] if self.polled else []
        for name in ("loss_up", "loss_down", "burst"):
            if getattr(self, name):
                out.append(f"--{name.replace('_', '-')} {getattr(self, name):g}")
        if self.seed != 1:
            out.append(f"--seed {self.seed}")
        if self.timeout_ms != 2000:
            out.append(f"--timeout-ms {self.timeout_ms}")
        if self.restart:
            out.append(f"--restart {self.restart} --restart-at-ms {self.restart_at_ms}")
        if self.lose_record:
            out.append(f"(and record {self.lose_record} lost once on its way up)")
        return " ".join(out)


# The exercises' runs (docs/exercises.md; tests/view checks each is the page's "watch it" line).
PRESETS = {
    # make run's default: the note's example of section 2.1.1 (README.md, plc/demo.py)
    "demo": Preset("the demo: 5 records, record 2 lost once on its way up", "", records=5,
                   lose_record=2),
    "clean": Preset("a clean transfer of 5 records", "", records=5),
    "ex2": Preset("the note's example: polled, bursty uplink loss", "2", records=4, polled=True,
                  loss_up=0.2, burst=4, seed=13, timeout_ms=1000),
    "ex3-up": Preset("uplink loss 30 %", "3", records=5, seed=3, loss_up=0.3),
    "ex3-down": Preset("downlink loss 30 %", "3", records=5, seed=3, loss_down=0.3),
    "ex4": Preset("a timeout that is too short (200 ms)", "4", records=5, timeout_ms=200),
    "ex5": Preset("bursts of 8 telegrams at 20 % uplink loss", "5", records=10, loss_up=0.2,
                  burst=8, seed=1),
    "ex6-central": Preset("the central PLC restarts at 1 s", "6", records=4,
                          restart="central"),
    "ex6-outstation": Preset("the outstation PLC restarts at 1 s", "6", records=4,
                             restart="outstation"),
    "ex8": Preset("20 records at 20 % loss both ways", "8", records=20, loss_up=0.2,
                  loss_down=0.2),
}
