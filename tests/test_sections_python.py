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


def _groups_from_pairs(pa, pb, group, ng):
    """The groups of :func:`sections._run_groups`' pairs as :func:`sections._groups` listed them
    before :func:`sections._run_group_lists` (sets per group, each sorted): the reference."""
    groups = [(set(), set()) for _ in range(ng)]
    for a, b, g in zip(pa.tolist(), pb.tolist(), group.tolist()):
        groups[g][0].add(a)
        groups[g][1].add(b)
    return [(sorted(a), sorted(b)) for a, b in groups]


def test_group_lists_from_runs_equal_the_pairs_grouped_in_python():
    import numpy as np
    from scipy import ndimage

    from contourmesh.fastpath import slice_labels
    from test_volumes_sections import _runs_of

    rng = np.random.default_rng(173)
    many = 0
    for t in range(200):
        h, w = int(rng.integers(2, 40)), int(rng.integers(2, 40))
        runs, ns = [], []
        for _ in range(2):
            m = ndimage.gaussian_filter(rng.random((h, w)), rng.uniform(0.5, 2.0)) > rng.uniform(0.4, 0.6)
            labels, n, _ = slice_labels(m)
            runs.append(_runs_of(labels))
            ns.append(n)
        comps = [np.arange(n, dtype=np.int64) if t % 3 == 0 or n == 0 else
                 np.sort(rng.choice(n, size=int(rng.integers(1, n + 1)), replace=False)).astype(np.int64)
                 for n in ns]
        y0, x0 = int(rng.integers(0, h // 2 + 1)), int(rng.integers(0, w // 2 + 1))
        y1, x1 = int(rng.integers(y0 + 1, h + 1)), int(rng.integers(x0 + 1, w + 1))
        inp, inq = np.zeros(ns[0] + 1, np.bool_), np.zeros(ns[1] + 1, np.bool_)
        inp[comps[0] + 1] = True
        inq[comps[1] + 1] = True
        pa, pb, group, ng, lone_p, lone_q = sections._run_groups(runs[0], runs[1], np.int64(y0), np.int64(y1),
                                                                  np.int64(x0), np.int64(x1), inp, inq)
        af, ast, bf, bst, lp, lq = sections._run_group_lists(runs[0], runs[1], y0, y1, x0, x1, ns[0], ns[1],
                                                              comps[0], comps[1])
        af, ast, bf, bst = af.tolist(), ast.tolist(), bf.tolist(), bst.tolist()
        got = [(af[ast[g]: ast[g + 1]], bf[bst[g]: bst[g + 1]]) for g in range(len(ast) - 1)]
        assert got == _groups_from_pairs(pa, pb, group, ng), t
        assert lp.tolist() == lone_p.tolist() and lq.tolist() == lone_q.tolist(), t
        many += any(len(a) > 1 or len(b) > 1 for a, b in got)
    assert many > 10  # (forks and merges among them, not only one-to-one groups)


def test_piece_kinds_kept_with_a_section_are_those_made_anew(monkeypatch):
    """A pair's piece kinds taken from its section's memory (:func:`sections._pair_kinds`) are
    those :func:`sections._piece_kinds` makes for the two layers, the layers themselves in their
    places; on volumes whose joins take sections from the build's memory, some are taken so."""
    from contourmesh.volumes import volume_to_mesh
    from test_sections_memory import _volumes

    pair_kinds, piece_kinds = sections._pair_kinds, sections._piece_kinds
    calls, made, kept = [0], [0], [0]

    def counted(ops, P, Q):
        made[0] += 1
        return piece_kinds(ops, P, Q)

    def checked(ops, P, Q):
        before = made[0]
        got = pair_kinds(ops, P, Q)
        kept[0] += made[0] == before  # (taken from memory: none made)
        want = piece_kinds(ops, P, Q)
        assert got == want
        if want is not None:
            for caps_or_kinds in want:
                for kind in caps_or_kinds:
                    assert all(x is P or x is Q for x in kind if isinstance(x, sections._Layer))
        calls[0] += 1
        return got

    monkeypatch.setattr(sections, "_piece_kinds", counted)
    monkeypatch.setattr(sections, "_pair_kinds", checked)
    monkeypatch.setattr(sections, "JOIN_MEMORY", 0)  # (joins asked for again are built again: their sections repeat)
    for v in _volumes():
        volume_to_mesh(v)
    assert calls[0] > kept[0] > 0
