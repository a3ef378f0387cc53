"""The shared memory of recent answers (``contourmesh._recent.Recent``) that the general mesher's
repeated questions use (bridged bands, band crossing tests, least-area bands, keyhole searches)."""

import threading

import pytest

from contourmesh import _recent, volumes
from contourmesh._recent import MISSING, Recent
from contourmesh.bands import _CROSSES_KEEP, _CROSSES_SEEN, bridges, optimal


def test_oldest_put_is_dropped_first_and_reads_do_not_keep_a_key():
    r = Recent(3)
    for k in "abc":
        r.put(k, k.upper())
    assert r.get("a") == "A"  # a read does not make "a" newer
    r.put("d", "D")
    assert "a" not in r and [k for k, _v in r.items()] == ["b", "c", "d"]
    assert len(r) == 3 and r.get("a") is None and r.get("a", MISSING) is MISSING


def test_a_kept_none_is_told_apart_from_a_missing_key():
    r = Recent(2)
    r.put("x", None)
    assert r.get("x", MISSING) is None
    assert r.get("y", MISSING) is MISSING
    r.clear()
    assert len(r) == 0 and r.get("x", MISSING) is MISSING


def test_putting_a_kept_key_again_replaces_its_answer():
    r = Recent(2)
    r.put("a", 1)
    r.put("b", 2)
    r.put("b", 3)  # (two threads that missed the same key put the same answer twice)
    # a put makes room first, as the memories did before they shared this class: "a" goes
    assert dict(r.items()) == {"b": 3}


@pytest.mark.parametrize("keep", [0, -1])
def test_keep_must_be_positive(keep):
    with pytest.raises(ValueError, match="keep must be at least 1"):
        Recent(keep)


def test_puts_from_threads_never_exceed_keep():
    r = Recent(8)

    def work(t):
        for i in range(2000):
            r.put((t, i), i)
            assert len(r) <= 8

    threads = [threading.Thread(target=work, args=(t,)) for t in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(r) == 8


def test_the_mesher_memories_are_recent_with_their_sizes():
    assert isinstance(_CROSSES_SEEN, Recent) and _CROSSES_SEEN.keep == _CROSSES_KEEP
    assert isinstance(optimal._SEEN, Recent) and optimal._SEEN.keep == optimal._SEEN_KEEP
    assert isinstance(bridges._KEYHOLES_SEEN, Recent) and bridges._KEYHOLES_SEEN.keep == bridges._KEYHOLES_KEEP
    assert isinstance(volumes._BANDS_SEEN, Recent) and volumes._BANDS_SEEN.keep == volumes._BANDS_KEEP
    assert _recent.MISSING is MISSING
