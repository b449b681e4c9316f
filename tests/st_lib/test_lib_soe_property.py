"""MIP_SoeReader under a random mix of everything that may go wrong at once (against both
relays): events at random times, read answers lost, acknowledgement requests and answers lost,
a logger that is slow or full for a while, triggered or cyclic reads. Whatever the mix: every
entry reaches the logger exactly once, in order, with the relay's values and time stamps, no
acknowledgement comes before its entries were stored, and the block ends caught up without an
error. Two seeds per relay in the quick tier, more in the full one."""
import random

import pytest

from soe_bench import Bench, expected
from test_lib_soe import ORIGIN, acks_after_stores, make_relay


@pytest.fixture(scope="module")
def wd(tmp_path_factory):
    return tmp_path_factory.mktemp("stlib_soe_prop")


def random_run(wd, relay, seed):
    rnd = random.Random(seed)
    n = rnd.randrange(10, 40)
    t, events = 0.0, []
    for k in range(n):
        t += rnd.choice([0.0, 0.001, 0.004, 0.03, 0.2])
        events.append((round(t, 3), [0x0100 + rnd.randrange(16), rnd.randrange(1, 2000),
                                     0x0101 + rnd.randrange(2), rnd.randrange(65536)]))
    mode = rnd.choice(["trigger", "cyclic"])
    b = Bench(wd, make_relay(relay, events), read_mode=mode, read_every=rnd.randrange(1, 5),
              delay=rnd.randrange(3), tAckRetry=rnd.choice([20, 50, 100]) * 1_000_000)
    for _ in range(400):
        r = rnd.random()
        if r < 0.05:
            b.client.lose_read_answer += 1
        elif r < 0.08:
            b.client.lose_write_answer += 1
        elif r < 0.10:
            b.client.lose_write_request += 1
        elif r < 0.12:
            b.logger.capacity = len(b.logger.stored)          # full for a while
        elif r < 0.20:
            b.logger.capacity = None
        b.step(rnd.randrange(1, 6))
        assert not b.fb["xError"], (seed, b.fb["eErrorId"])
    b.logger.capacity = None
    b.client.lose_read_answer = b.client.lose_write_answer = b.client.lose_write_request = 0
    done = b.run_until(lambda: len(b.logger.stored) >= n and b.fb["xCaughtUp"], 3000)
    assert done, (seed, len(b.logger.stored), n, b.fb["eWaitReason"])
    assert b.logger.stored == expected(events, ORIGIN), seed
    acks_after_stores(b.log)
    assert b.relay.entries() == 0 and not b.fb["xError"]


@pytest.mark.parametrize("relay", ["py", "c"])
@pytest.mark.parametrize("seed", [11, 12])
def test_random_faults_quick(wd, relay, seed):
    random_run(wd, relay, seed)


@pytest.mark.slow
@pytest.mark.parametrize("relay", ["py", "c"])
@pytest.mark.parametrize("seed", range(100, 140))
def test_random_faults_full(wd, relay, seed):
    random_run(wd, relay, seed)
