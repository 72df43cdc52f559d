"""YAML decoders: warm children reused, killed when a document outlasts its time, replaced
when they stop, never shared with a forked process."""

from __future__ import annotations

import io
import json
import multiprocessing
import struct
import threading

import psutil
import pytest

from pickstop.api import yaml_child
from pickstop.runtime.yaml_decoders import ChildLost, DecodeTimeout, YamlDecoders

BIG = ("items:\n" + "".join(f"  - {{a: {i}, b: [1, 2.5, x{i}]}}\n" for i in range(4000))).encode()


@pytest.fixture()
def decoders():
    d = YamlDecoders()
    yield d
    d.close()


def _doc(answer: bytes):
    return json.loads(answer)["doc"]


def test_a_warm_child_decodes_one_document_after_another(decoders):
    assert _doc(decoders.decode(b"a: 1\n", 5.0)) == {"a": 1}
    (pid,) = decoders.pids()
    assert _doc(decoders.decode(b"b: [x, 2.5]\n", 5.0)) == {"b": ["x", 2.5]}
    assert json.loads(decoders.decode(b"a: !!binary aGVsbG8=\n", 5.0))["error"]
    assert decoders.pids() == [pid], "the same child answered all three"


def test_a_document_that_outlasts_its_time_kills_its_child(decoders):
    decoders.decode(b"a: 1\n", 5.0)
    (pid,) = decoders.pids()
    with pytest.raises(DecodeTimeout):
        decoders.decode(BIG, 0.001)
    assert not psutil.pid_exists(pid) or psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
    assert decoders.pids() == []
    assert len(_doc(decoders.decode(BIG, 5.0))["items"]) == 4000


def test_a_child_that_stopped_while_idle_is_replaced(decoders):
    decoders.decode(b"a: 1\n", 5.0)
    (pid,) = decoders.pids()
    psutil.Process(pid).kill()
    psutil.Process(pid).wait(5)
    assert _doc(decoders.decode(b"a: 2\n", 5.0)) == {"a": 2}
    assert decoders.pids() != [pid]


def test_a_child_lost_on_a_fresh_document_is_reported(decoders, monkeypatch):
    from pickstop.runtime import yaml_decoders

    class Gone(yaml_decoders._Child):
        def ask(self, data, seconds):
            self.kill()
            raise ChildLost

    monkeypatch.setattr(yaml_decoders, "_Child", Gone)
    with pytest.raises(ChildLost):
        decoders.decode(b"a: 1\n", 5.0)


def test_at_most_two_decode_at_once(decoders):
    seen: set[int] = set()
    lock = threading.Lock()
    real = decoders._take

    def take():
        child = real()
        with lock:
            seen.add(child.proc.pid)
        return child

    decoders._take = take
    threads = [threading.Thread(target=decoders.decode, args=(BIG, 30.0)) for _ in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert 1 <= len(seen) <= 2 and len(decoders.pids()) <= 2


def _forked(decoders, q):
    decoders.decode(b"a: 1\n", 5.0)
    q.put(decoders.pids())


def test_a_forked_process_starts_children_of_its_own(decoders):
    decoders.decode(b"a: 1\n", 5.0)
    mine = decoders.pids()
    ctx = multiprocessing.get_context("fork")
    q = ctx.Queue()
    p = ctx.Process(target=_forked, args=(decoders, q))
    p.start()
    theirs = q.get(timeout=30)
    p.join(30)
    assert theirs and set(theirs).isdisjoint(mine)
    assert decoders.pids() == mine and all(psutil.pid_exists(x) for x in mine)


def _framed(*docs: bytes) -> io.BytesIO:
    return io.BytesIO(b"".join(struct.pack(">Q", len(d)) + d for d in docs))


def _answers(out: io.BytesIO) -> list[dict]:
    raw, got = out.getvalue(), []
    while raw:
        (n,) = struct.unpack(">Q", raw[:8])
        got.append(json.loads(raw[8 : 8 + n]))
        raw = raw[8 + n :]
    return got


def test_the_child_answers_each_framed_document_until_its_input_ends():
    out = io.BytesIO()
    yaml_child.serve(_framed(b"a: 1\n", b"[1, 2]\n", b"a: *x\n"), out)
    got = _answers(out)
    assert got[:2] == [{"doc": {"a": 1}}, {"doc": [1, 2]}] and "error" in got[2]


def test_the_child_stops_after_it_ran_out_of_memory(monkeypatch):
    def exhausted(text):
        raise MemoryError

    monkeypatch.setattr(yaml_child, "load", exhausted)
    out = io.BytesIO()
    yaml_child.serve(_framed(b"a: 1\n", b"b: 2\n"), out)
    assert _answers(out) == [{"error": "the document takes too much memory to decode"}]


def test_a_timeout_is_a_422_and_the_next_body_decodes(monkeypatch):
    from pickstop.api import body
    from pickstop.api.problems import Problem

    monkeypatch.setattr(body, "YAML_SECONDS", 0.001)
    with pytest.raises(Problem) as e:
        body.decode_yaml(BIG)
    assert e.value.status == 422 and "took more than" in e.value.detail
    monkeypatch.setattr(body, "YAML_SECONDS", 5.0)
    assert body.decode_yaml(b"name: x\n") == {"name": "x"}


def test_a_child_lost_without_an_answer_is_a_422(monkeypatch):
    from pickstop.api import body
    from pickstop.api.problems import Problem
    from pickstop.runtime import yaml_decoders

    def lost(data, seconds):
        raise ChildLost

    monkeypatch.setattr(yaml_decoders.DECODERS, "decode", lost)
    with pytest.raises(Problem) as e:
        body.decode_yaml(b"name: x\n")
    assert e.value.status == 422 and "could not be decoded" in e.value.detail
