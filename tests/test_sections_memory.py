"""The memory of sectioned joins within one build of the bridged joins (sections.JoinMemory): the
same meshes, bit for bit, as without it, with fewer sectioned joins built; and a remembered join is
built again wherever something it reads changed."""

import numpy as np
import pytest
from scipy import ndimage

from contourmesh import sections
from contourmesh.volumes import volume_to_mesh
from test_volumes_sections import _blobs, _sparse_rings, _two_cs


def _volumes():
    vols = [_blobs(), _blobs(seed=3, shape=(6, 18, 18)), _two_cs()]
    # (with sparse rings each of these asks for some sectioned join again after a restart)
    for seed in (5, 9, 22, 46):
        rng = np.random.default_rng(seed)
        vols.append(ndimage.gaussian_filter(rng.random((8, 32, 32)), 1.2) > 0.5 + 0.03 * rng.standard_normal())
    return vols


def _same(a, b):
    assert a.vertices.tobytes() == b.vertices.tobytes() and a.faces.tobytes() == b.faces.tobytes()
    assert a.meta == b.meta


def _counting(monkeypatch):
    calls = [0]
    join = sections.sectioned_join

    def counted(*a, **kw):
        calls[0] += 1
        return join(*a, **kw)

    monkeypatch.setattr(sections, "sectioned_join", counted)
    return calls


@pytest.mark.parametrize("sparse", [True, False])
def test_remembered_sectioned_joins_give_the_same_meshes(monkeypatch, sparse):
    """With the memory (the default) and without it (``JOIN_MEMORY = 0``): the same meshes, and
    no more sectioned joins built with it (with sparse rings, fewer)."""
    if sparse:
        _sparse_rings(monkeypatch)
    calls = _counting(monkeypatch)
    vols = _volumes()
    built = {}
    meshes = {}
    for keep in (0, sections.JOIN_MEMORY):
        monkeypatch.setattr(sections, "JOIN_MEMORY", keep)
        calls[0] = 0
        meshes[keep] = [volume_to_mesh(v) for v in vols]
        built[keep] = calls[0]
    for a, b in zip(meshes[0], meshes[sections.JOIN_MEMORY]):
        _same(a, b)
    assert built[0] > 0 and built[sections.JOIN_MEMORY] <= built[0]
    if sparse:
        assert built[sections.JOIN_MEMORY] < built[0]


def test_the_lobster_remembers_sectioned_joins(monkeypatch, shared_data):
    """The lobster's pass restarts after joins fall back to exact and asks for sectioned joins
    again: some are answered from memory, and the mesh is the same bit for bit."""
    from contourmesh.io import read_volume

    vol, _, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    calls = _counting(monkeypatch)
    monkeypatch.setattr(sections, "JOIN_MEMORY", 0)
    ref = volume_to_mesh(vol)
    without = calls[0]
    monkeypatch.setattr(sections, "JOIN_MEMORY", 32)
    calls[0] = 0
    got = volume_to_mesh(vol)
    _same(got, ref)
    assert calls[0] < without


class _Stub:
    """A stand-in for sectioned_join that records its calls and reads the planes it is told to."""

    def __init__(self, reads=(0, 1)):
        self.calls, self.reads = 0, reads

    def __call__(self, ops, k, ga, gb, slices, zs, poly, edges_of, double, caps, triangulation, polygon, grid,
                 topology_first=False, max_area=None, memory=None):
        self.calls += 1
        for kk in self.reads:
            edges_of(k + kk)
        return object()


class _Holes:
    def __init__(self, n):
        self.holes = [[] for _ in range(n)]


def _square(x0, y0, s=1.0):
    return np.array([[x0, y0], [x0 + s, y0], [x0 + s, y0 + s], [x0, y0 + s]])


def test_a_remembered_join_is_built_again_where_what_it_reads_changed(monkeypatch):
    """The memory answers only where the rings, the bound, the lidded holes and, in each plane whose
    edges the join read, the edges near its rings are the same; edges elsewhere, and the edges of
    a plane it did not read, do not matter."""
    stub = _Stub(reads=(0,))
    monkeypatch.setattr(sections, "sectioned_join", stub)
    slices = [_Holes(2), _Holes(2)]
    rings = {(0, 0, -1): _square(0, 0), (1, 0, -1): _square(0.5, 0), (0, 1, -1): _square(5, 5),
             (1, 1, -1): _square(5, 5)}

    def poly(kk, c, h):
        return rings[kk, c, h]

    near = (np.array([[0.5, 0.5]]), np.array([[0.5, 2.0]]))  # (meets the box of component 0's ring)
    far = (np.array([[3.0, 3.0]]), np.array([[4.0, 3.0]]))
    edges = {0: tuple(np.concatenate([n, f]) for n, f in zip(near, far)), 1: far}
    memory = sections.JoinMemory()
    args = dict(ops=None, k=0, ga=[0], gb=[0], slices=slices, zs=[0.0, 1.0], double=set(), caps="flat",
                triangulation="wiederhold", polygon="mlp", grid=(0.0, 0.0, 1.0, 1.0))

    def join(**kw):
        return memory.join(**dict(args, poly=poly, edges_of=lambda kk: edges[kk], **kw))

    first = join(max_area=2.0)
    assert stub.calls == 1
    assert join(max_area=2.0) is first and stub.calls == 1
    # other edges far from the rings, and other edges of the plane it did not read
    edges[0] = tuple(np.concatenate([n, f + 10.0]) for n, f in zip(near, far))
    edges[1] = (np.zeros((0, 2)), np.zeros((0, 2)))
    assert join(max_area=2.0) is first and stub.calls == 1
    # an edge near the rings moved
    edges[0] = (edges[0][0] + np.array([[0.25, 0.0], [0.0, 0.0]]), edges[0][1])
    again = join(max_area=2.0)
    assert again is not first and stub.calls == 2
    assert join(max_area=2.0) is again and stub.calls == 2
    # another bound, lidded holes of its components, rings
    join(max_area=3.0)
    assert stub.calls == 3
    join(max_area=2.0, double={(0, 0, 0)})
    assert stub.calls == 4
    join(max_area=2.0, double={(0, 1, 0)})  # (a hole of another component: the same join)
    assert stub.calls == 4
    rings[1, 0, -1] = _square(0.5, 0.25)
    join(max_area=2.0)
    assert stub.calls == 5
    # a memory that keeps nothing builds every time
    memory = sections.JoinMemory(keep=0)
    join(max_area=2.0)
    join(max_area=2.0)
    assert stub.calls == 7


@pytest.mark.parametrize("sparse", [True, False])
def test_remembered_section_slices_give_the_same_meshes(monkeypatch, sparse):
    """With the build's memory of section slices (the default) and without it (``SECTION_MEMORY =
    0``; the joins' memory off too, so that joins asked for again make their sections again): the
    same meshes, and some sections taken from memory with it, none without."""
    if sparse:
        _sparse_rings(monkeypatch)
    monkeypatch.setattr(sections, "JOIN_MEMORY", 0)
    hits = [0]
    get = sections.SectionSlices.get

    def counted(self, key):
        got = get(self, key)
        hits[0] += got is not None
        return got

    monkeypatch.setattr(sections.SectionSlices, "get", counted)
    vols = _volumes()
    meshes, found = {}, {}
    for keep in (0, sections.SECTION_MEMORY):
        monkeypatch.setattr(sections, "SECTION_MEMORY", keep)
        hits[0] = 0
        meshes[keep] = [volume_to_mesh(v) for v in vols]
        found[keep] = hits[0]
    for a, b in zip(meshes[0], meshes[sections.SECTION_MEMORY]):
        _same(a, b)
    assert found[0] == 0 and found[sections.SECTION_MEMORY] > 0


def test_the_lobster_takes_section_slices_from_memory(monkeypatch, shared_data):
    """The lobster's sectioned joins make some sections that a join made before (or its own other
    half): taken from memory, the same mesh bit for bit."""
    from contourmesh.io import read_volume

    vol, _, _ = read_volume(shared_data / "volumes" / "dgtal" / "lobster.vol", threshold=60)
    hits = [0]
    get = sections.SectionSlices.get

    def counted(self, key):
        got = get(self, key)
        hits[0] += got is not None
        return got

    monkeypatch.setattr(sections.SectionSlices, "get", counted)
    monkeypatch.setattr(sections, "SECTION_MEMORY", 0)
    ref = volume_to_mesh(vol)
    assert hits[0] == 0
    monkeypatch.setattr(sections, "SECTION_MEMORY", 24)
    got = volume_to_mesh(vol)
    _same(got, ref)
    assert hits[0] > 0
