"""The Python of a sectioned join made lighter (issue 16): each faster form against the one it
replaces, kept as its reference, on every case or on random ones."""

import itertools

import pytest

from contourmesh import sections


def _paths(depth):
    """Every pair path of a join with ``depth`` splits that can be decided (split or not)."""
    out = [()]
    for d in range(1, depth + 1):
        out.extend(itertools.product((0, 1), repeat=d))
    return out


@pytest.mark.parametrize("depth", [0, 1, 2, 3])
def test_the_stack_table_filtered_is_the_recursive_stacks(depth):
    paths = _paths(depth)
    # every way the splits so far can stand (undecided, split, unsplit) for every pair path
    # (depth 3: a random share of them, as there are 3^15)
    choices = list(itertools.product((None, True, False), repeat=len(paths))) if depth < 3 else None
    if choices is None:
        import random
        rnd = random.Random(7)
        choices = [tuple(rnd.choice((None, True, False)) for _ in paths) for _ in range(3000)]
    seen = set()
    for pick in choices:
        split_at = {p: v for p, v in zip(paths, pick) if v is not None}
        want = sorted(sections._stacks_reference(split_at, (), depth), key=len)
        got = [st for st, unsplit, _ in sections._stack_table(depth)
               if not any(split_at.get(p) is False for p in st) and not any(split_at.get(p) is True for p in unsplit)]
        assert got == want
        seen.add(len(got))
    assert len(seen) > 1  # (some choices allow fewer stacks than others)
    for st, _, order in sections._stack_table(depth):
        assert list(order) == sorted(st, key=len)
