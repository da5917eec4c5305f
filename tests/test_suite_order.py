"""The suite's run order (tests/conftest.py): under `--dist worksteal` each worker is first handed a
consecutive chunk of the collection (the pending tests // workers, then what is left // the workers
left); every chunk starts with its share of the groups of tests marked `slow`."""

from __future__ import annotations

from tests.conftest import worker_chunks


def test_each_workers_first_chunk_starts_with_its_share_of_the_slow_tests():
    slow, rest = [["s0"], ["s1", "s1b"], ["s2"], ["s3"], ["s4"]], [f"r{i}" for i in range(20)]
    first, second = worker_chunks(slow, rest, 2)
    assert (len(first), len(second)) == (13, 13)  # 26 // 2, then the 13 left
    assert first[:3] == ["s0", "s2", "s4"] and second[:3] == ["s1", "s1b", "s3"]  # a group stays together
    assert first[3:] + second[3:] == rest  # the others keep their order
    three = worker_chunks(slow, rest, 3)
    assert [len(chunk) for chunk in three] == [8, 9, 9] and [chunk[0] for chunk in three] == ["s0", "s1", "s2"]
    assert worker_chunks(slow, rest, 1) == [["s0", "s1", "s1b", "s2", "s3", "s4", *rest]]  # no xdist: slow first


def test_more_slow_tests_than_a_chunk_holds_are_all_kept():
    chunks = worker_chunks([["s0", "s1", "s2"], ["s3"]], ["r0"], 2)
    assert sorted(item for chunk in chunks for item in chunk) == ["r0", "s0", "s1", "s2", "s3"]
