"""A group's bridge plan from the runs of its overlap (:func:`contourmesh.volumes._bridge_plan` by
:func:`contourmesh.volumes._overlap_plan` and :func:`contourmesh.tracing.overlap_hole_labels`),
against the form it replaced (the overlap's mask, then :func:`contourmesh.tracing.overlap_holes`
painting its background's labels): the same numbers and the same plans, bit for bit, on random
masks and groups and on every group the mesher plans on parts of the shared volumes."""

import numpy as np

from contourmesh import tracing, volumes


def _bridge_plan_reference(A, B, ga, gb):
    """volumes._bridge_plan as it was: the overlap's mask (``_overlap_pairs``), ``overlap_holes`` of
    it with its background's labels painted, and each hole's label read off them."""
    sl = [A.objects[a] for a in ga] + [B.objects[b] for b in gb]
    y0 = min(s[0].start for s in sl)
    y1 = max(s[0].stop for s in sl)
    x0 = min(s[1].start for s in sl)
    x1 = max(s[1].stop for s in sl)
    o, npairs = volumes._overlap_pairs(A.labels[y0:y1, x0:x1], B.labels[y0:y1, x0:x1], volumes._group_lut(A.n, ga),
                                       volumes._group_lut(B.n, gb), np.int64(len(ga)), np.int64(len(gb)))
    if npairs != len(ga) + len(gb) - 1:
        return None
    no, blab, nbl, n_out = tracing.overlap_holes(o)
    if no != npairs:
        return None
    ext = blab[0, 0]
    if n_out != no:
        return None
    holes_o = set(range(1, nbl + 1)) - {ext}

    def where(S, comps):
        at = {}
        for c in comps:
            csl, masks = S.hole_masks[c]
            for h in range(len(masks)):
                y, x = masks.first_pixel(h)
                lab = int(blab[y + csl[0].start - y0 + 1, x + csl[1].start - x0 + 1])
                at.setdefault(lab, []).append((c, h))
        return at

    wa, wb = where(A, ga), where(B, gb)
    open_a, open_b = wa.pop(ext, []), wb.pop(ext, [])
    if any(len(v) > 1 for v in wa.values()) or any(len(v) > 1 for v in wb.values()):
        return None
    if set(wa) | set(wb) != holes_o:
        return None
    tubes = [(wa[lab][0], wb[lab][0]) for lab in sorted(set(wa) & set(wb))]
    lids_a = [wa[lab][0] for lab in sorted(set(wa) - set(wb))]
    lids_b = [wb[lab][0] for lab in sorted(set(wb) - set(wa))]
    return tubes, lids_a, lids_b, open_a, open_b


def _same_plan(a, b):
    if a is None or b is None:
        return a is None and b is None
    return len(a) == len(b) == 5 and all(type(x) is type(y) and x == y for x, y in zip(a, b))


def test_hole_labels_equal_the_painted_labels():
    rng = np.random.default_rng(1591)
    inside, holes = set(), set()
    for trial in range(1200):
        h, w = (int(v) for v in rng.integers(1, 34, 2))
        o = rng.random((h, w)) < rng.uniform(0.03, 0.97)
        if trial % 3 == 0:  # (a view with strides, as the callers may pass)
            o = np.ascontiguousarray(o[::-1])[::-1]
        n, blab, nb, n_out = tracing.overlap_holes(o)
        ys, xs = np.nonzero(np.ones((h + 2, w + 2), bool))  # every pixel of the padded box
        pick = rng.permutation(len(ys))[: int(rng.integers(0, len(ys) + 1))]  # and some, in any order
        for qy, qx in ((ys, xs), (ys[pick], xs[pick])):
            got_n, labels, got_nb, got_out, ext = tracing.overlap_hole_labels(o, qy, qx)
            assert (int(got_n), int(got_nb), int(got_out), int(ext)) == (int(n), int(nb), int(n_out), int(blab[0, 0]))
            assert labels.dtype == np.int64 and np.array_equal(labels, blab[qy, qx])
        inside.add(n_out < n)
        holes.add(nb > 1)
    assert inside == holes == {True, False}


def test_overlap_plan_equals_the_mask_and_its_painted_labels():
    rng = np.random.default_rng(1592)
    loops, kinds = 0, set()
    for trial in range(600):
        h, w = int(rng.integers(1, 30)), int(rng.integers(1, 30))
        na, nb = int(rng.integers(1, 5)), int(rng.integers(1, 5))
        dt = [np.uint8, np.int32, np.uint16, np.int64][trial % 4]
        # blobs rather than noise (fewer pairs, so that many groups form no loop)
        la = (rng.integers(0, na + 1, (h // 3 + 2, w // 3 + 2)).repeat(3, 0).repeat(3, 1)[:h, :w]).astype(dt)
        lb = (rng.integers(0, nb + 1, (h // 4 + 2, w // 4 + 2)).repeat(4, 0).repeat(4, 1)[1:h + 1, :w]).astype(dt)
        ga = sorted(rng.choice(na, int(rng.integers(1, na + 1)), replace=False).tolist())
        gb = sorted(rng.choice(nb, int(rng.integers(1, nb + 1)), replace=False).tolist())
        if trial % 5 == 0:  # a ring below (a hole in the overlap) around a blob, all covered above
            h, w = int(rng.integers(5, 30)), int(rng.integers(5, 30))
            yy, xx = np.mgrid[:h, :w]
            r = np.maximum(abs(yy - h // 2), abs(xx - w // 2))
            la = np.where(r == 0, 2, np.where((r >= 2) & (r <= 3), 1, 0)).astype(dt)
            lb = np.ones((h, w), dt)
            na, nb, ga, gb = 2, 1, ([0, 1] if trial % 10 else [0]), [0]
        lut_a, lut_b = volumes._group_lut(na, ga), volumes._group_lut(nb, gb)
        ys, xs = np.nonzero(rng.random((h + 2, w + 2)) < 0.3)
        o, npairs = volumes._overlap_pairs(la, lb, lut_a, lut_b, np.int64(len(ga)), np.int64(len(gb)))
        got = volumes._overlap_plan(la, lb, lut_a, lut_b, np.int64(len(ga)), np.int64(len(gb)), ys.astype(np.int64),
                                    xs.astype(np.int64), np.int64(1))
        assert got[0] == npairs
        if npairs != len(ga) + len(gb) - 1:
            loops += 1
            assert got[1] == -1 and len(got[2]) == 0
            continue
        n, blab, nbl, n_out = tracing.overlap_holes(o)
        assert (int(got[1]), int(got[3]), int(got[4]), int(got[5])) == (int(n), int(nbl), int(n_out), int(blab[0, 0]))
        assert np.array_equal(got[2], blab[ys, xs])
        kinds.add((n == npairs, n_out == n, nbl > 1))
    assert 0 < loops < 600 and len(kinds) >= 4


def _runs_of(labels):
    """The runs of a label image as ``_Slice.kept_runs`` holds them: int32 ``(4, n)`` ``[row, first
    column, end column, component]`` (0-based), in raster order."""
    out = []
    for y, row in enumerate(labels.tolist()):
        x = 0
        while x < len(row):
            if row[x]:
                s = x
                while x < len(row) and row[x] == row[s]:
                    x += 1
                out.append((y, s, x, row[s] - 1))
            else:
                x += 1
    return np.array(out, dtype=np.int32).reshape(-1, 4).T.copy()


def test_overlap_plan_from_runs_equals_the_label_images():
    rng = np.random.default_rng(1593)
    loops, kinds = 0, set()
    for trial in range(600):
        H, W = int(rng.integers(1, 36)), int(rng.integers(1, 36))
        na, nb = int(rng.integers(1, 6)), int(rng.integers(1, 6))
        # blobs of labels in a whole image (runs of different labels touch), a box within it
        la = rng.integers(0, na + 1, (H // 3 + 2, W // 3 + 2)).repeat(3, 0).repeat(3, 1)[:H, :W].astype(np.int32)
        lb = rng.integers(0, nb + 1, (H // 2 + 2, W // 2 + 2)).repeat(2, 0).repeat(2, 1)[1:H + 1, :W].astype(np.int32)
        if trial % 5 == 0:  # a ring below around a blob, all covered above
            yy, xx = np.mgrid[:H, :W]
            r = np.maximum(abs(yy - H // 2), abs(xx - W // 2))
            la = np.where(r == 0, 2, np.where((r >= 2) & (r <= 3), 1, 0)).astype(np.int32)
            lb, na, nb = np.ones((H, W), np.int32), max(na, 2), max(nb, 1)
        ga = sorted(rng.choice(na, int(rng.integers(1, na + 1)), replace=False).tolist())
        gb = sorted(rng.choice(nb, int(rng.integers(1, nb + 1)), replace=False).tolist())
        y0, x0 = int(rng.integers(0, H)), int(rng.integers(0, W))
        y1, x1 = int(rng.integers(y0 + 1, H + 1)), int(rng.integers(x0 + 1, W + 1))
        if trial % 3 == 0:
            y0, x0, y1, x1 = 0, 0, H, W
        h, w = y1 - y0, x1 - x0
        lut_a, lut_b = volumes._group_lut(na, ga), volumes._group_lut(nb, gb)
        ys, xs = np.nonzero(rng.random((h + 2, w + 2)) < 0.4)
        ys, xs = ys.astype(np.int64), xs.astype(np.int64)
        args = (lut_a, lut_b, np.int64(len(ga)), np.int64(len(gb)), ys, xs, np.int64(1))
        want = volumes._overlap_plan(la[y0:y1, x0:x1], lb[y0:y1, x0:x1], *args)
        got = volumes._overlap_plan_runs(_runs_of(la), _runs_of(lb), np.int64(y0), np.int64(y1), np.int64(x0),
                                         np.int64(x1), *args)
        assert [int(v) for v in (got[0], got[1], got[3], got[4], got[5])] == \
            [int(v) for v in (want[0], want[1], want[3], want[4], want[5])], trial
        assert got[2].dtype == np.int64 and np.array_equal(got[2], want[2]), trial
        loops += int(want[1]) == -1
        if int(want[1]) >= 0:
            kinds.add((int(want[1]) == int(want[0]), int(want[4]) == int(want[1]), int(want[3]) > 1))
    assert 0 < loops < 600 and len(kinds) >= 4


def test_the_meshers_plans_equal_the_reference(shared_data, monkeypatch):
    """Every group the general mesher plans (its pass over the slices and the sectioned joins)
    while meshing parts of the shared volumes, and every group whose exact join's area it takes."""
    import contourmesh
    from contourmesh.io import read_volume

    real = volumes._bridge_plan
    seen = []

    def spy(A, B, ga, gb):
        got = real(A, B, ga, gb)
        seen.append((got, _bridge_plan_reference(A, B, ga, gb), A.kept_runs() is not None and B.kept_runs() is not None))
        return got

    real_area = volumes._exact_area
    groups = []

    def spy_area(slices, zs, k, ga, gb, *args):
        groups.append((slices[k], slices[k + 1], list(ga), list(gb)))
        return real_area(slices, zs, k, ga, gb, *args)

    monkeypatch.setattr(volumes, "_bridge_plan", spy)
    monkeypatch.setattr(volumes, "_exact_area", spy_area)
    lobster, _, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    z = np.load(shared_data / "volumes" / "cgogn" / "liver.npz")
    liver = np.asarray(z["volume"] if "volume" in z.files else z["mask"]) > 0
    for vol in (lobster[15:40], liver[200:230]):
        contourmesh.mesh(vol)
    assert len(seen) > 20
    assert any(got is None for got, _, _ in seen) and any(got is not None and got[0] for got, _, _ in seen)
    assert any(runs for _, _, runs in seen)
    for got, want, _ in seen:
        assert _same_plan(got, want)
    # and _exact_area's pixels of one group only, from the runs, against the label images
    assert len(groups) > 5 and all(A.kept_runs() is not None and B.kept_runs() is not None for A, B, _, _ in groups)
    for A, B, ga, gb in groups:
        sl = [A.objects[a] for a in ga] + [B.objects[b] for b in gb]
        y0, y1 = min(s[0].start for s in sl), max(s[0].stop for s in sl)
        x0, x1 = min(s[1].start for s in sl), max(s[1].stop for s in sl)
        want = np.count_nonzero(tracing.label_mask(A.labels[y0:y1, x0:x1], A.n, ga)
                                ^ tracing.label_mask(B.labels[y0:y1, x0:x1], B.n, gb))
        got = volumes._count_one_side_runs(A.kept_runs(), B.kept_runs(), np.int64(y0), np.int64(y1), np.int64(x0),
                                           np.int64(x1), volumes._group_lut(A.n, ga), volumes._group_lut(B.n, gb))
        assert int(got) == int(want)


def test_one_side_count_from_runs_equals_the_label_images():
    # _exact_area's pixels of one group only, from the slices' runs in a box's rows
    rng = np.random.default_rng(1594)
    counts = set()
    for trial in range(500):
        H, W = int(rng.integers(1, 36)), int(rng.integers(1, 36))
        na, nb = int(rng.integers(1, 6)), int(rng.integers(1, 6))
        la = rng.integers(0, na + 1, (H // 3 + 2, W // 3 + 2)).repeat(3, 0).repeat(3, 1)[:H, :W].astype(np.int32)
        lb = rng.integers(0, nb + 1, (H // 2 + 2, W // 2 + 2)).repeat(2, 0).repeat(2, 1)[1:H + 1, :W].astype(np.int32)
        if trial % 10 == 0:  # the same pixels on both sides
            lb, nb = la.copy(), na
        ga = sorted(rng.choice(na, int(rng.integers(1, na + 1)), replace=False).tolist())
        gb = ga if trial % 10 == 0 else sorted(rng.choice(nb, int(rng.integers(1, nb + 1)), replace=False).tolist())
        y0, x0 = int(rng.integers(0, H)), int(rng.integers(0, W))
        y1, x1 = int(rng.integers(y0 + 1, H + 1)), int(rng.integers(x0 + 1, W + 1))
        if trial % 3 == 0:
            y0, x0, y1, x1 = 0, 0, H, W
        lut_a, lut_b = volumes._group_lut(na, ga), volumes._group_lut(nb, gb)
        want = volumes._count_one_side(la[y0:y1, x0:x1], lb[y0:y1, x0:x1], lut_a, lut_b)
        got = volumes._count_one_side_runs(_runs_of(la), _runs_of(lb), np.int64(y0), np.int64(y1), np.int64(x0),
                                           np.int64(x1), lut_a, lut_b)
        assert int(got) == int(want), trial
        counts.add(min(int(want), 3))
    assert counts == {0, 1, 2, 3}
