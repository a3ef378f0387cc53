"""The sample-data registry: entries, mirror lookup with sha256 checks, download errors."""

import json
import os
import re
import shutil
import sys
import types
from pathlib import Path

import pytest

from contourmesh import datasets

MIRROR = Path(os.environ.get(datasets.ENV_VAR, Path(__file__).resolve().parents[2] / "shared" / "data"))


def need_mirror():
    if not (MIRROR / "manifest.json").exists():
        pytest.skip(f"no data mirror at {MIRROR} (set {datasets.ENV_VAR} to the ../shared/data folder)")


def test_registry_entries_are_complete():
    assert len(datasets.REGISTRY) == 49
    for name, e in datasets.REGISTRY.items():
        assert name == e.name == Path(e.path).name
        assert re.fullmatch(r"[0-9a-f]{64}", e.sha256)
        assert e.license and e.kind in ("volume", "mesh", "contour")
        if name.endswith(".npz"):
            assert e.url is None and "derived" in e.license
        else:
            assert re.fullmatch(r"https://github\.com/[\w.-]+/[\w.-]+/raw/[0-9a-f]{12}/\S+", e.url), e.url
            assert e.url.endswith("/" + name)
    assert datasets.REGISTRY["lobsterCroped.vol"].url.endswith("/tests/samples/lobsterCroped.vol")
    assert datasets.REGISTRY["rtss.dcm"].url.startswith("https://github.com/dicompyler/dicompyler-core/raw/0d5729d7a241/")
    assert datasets.info("volumes/dgtal/Al.100.vol") is datasets.REGISTRY["Al.100.vol"]


def test_registry_matches_the_manifest():
    need_mirror()
    manifest = json.loads((MIRROR / "manifest.json").read_text())["files"]
    assert {e.path for e in datasets.REGISTRY.values()} == set(manifest)
    for e in datasets.REGISTRY.values():
        assert e.sha256.startswith(manifest[e.path]["sha256_16"]), e.path


def test_fetch_from_mirror_verifies(tmp_path, monkeypatch):
    need_mirror()
    monkeypatch.setenv(datasets.ENV_VAR, str(MIRROR))
    p = datasets.fetch("bunny-64.vol")
    assert p == MIRROR / "volumes" / "dgtal" / "bunny-64.vol" and p.is_file()
    assert datasets.fetch("liver.npz").is_file()  # derived files come from the mirror
    # a corrupted mirror copy is refused
    bad = tmp_path / "volumes" / "dgtal"
    bad.mkdir(parents=True)
    shutil.copy(p, bad / "bunny-64.vol")
    with open(bad / "bunny-64.vol", "ab") as fh:
        fh.write(b"\0")
    with pytest.raises(ValueError, match=r"bunny-64.vol.*expected sha256 a2227cf6"):
        datasets.fetch("bunny-64.vol", mirror=tmp_path)


def test_fetch_errors_without_mirror(tmp_path, monkeypatch):
    monkeypatch.delenv(datasets.ENV_VAR, raising=False)
    with pytest.raises(ValueError, match="unknown dataset 'bunny.vol'; did you mean"):
        datasets.fetch("bunny.vol")
    with pytest.raises(FileNotFoundError, match="derived file.*CONTOURMESH_DATA"):
        datasets.fetch("liver.npz")
    with pytest.raises(FileNotFoundError, match="download=False"):
        datasets.fetch("cat10.vol", mirror=tmp_path, download=False)


def test_download_failure_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.delenv(datasets.ENV_VAR, raising=False)
    calls = []

    def retrieve(url, known_hash, fname, path, progressbar):
        calls.append((url, known_hash, fname, Path(path)))
        raise OSError("network is unreachable")

    fake = types.SimpleNamespace(retrieve=retrieve, os_cache=lambda name: tmp_path / name)
    monkeypatch.setitem(sys.modules, "pooch", fake)
    with pytest.raises(ConnectionError, match=r"cat10.vol.*network is unreachable.*CONTOURMESH_DATA"):
        datasets.fetch("cat10.vol")
    url, known_hash, fname, path = calls[0]
    assert url == datasets.REGISTRY["cat10.vol"].url
    assert known_hash == "sha256:" + datasets.REGISTRY["cat10.vol"].sha256
    assert fname == "cat10.vol" and path == tmp_path / "contourmesh" / "volumes" / "dgtal"


def test_download_success_returns_the_cached_path(tmp_path, monkeypatch):
    monkeypatch.delenv(datasets.ENV_VAR, raising=False)

    def retrieve(url, known_hash, fname, path, progressbar):
        Path(path).mkdir(parents=True, exist_ok=True)
        (Path(path) / fname).write_bytes(b"x")
        return str(Path(path) / fname)

    monkeypatch.setitem(sys.modules, "pooch", types.SimpleNamespace(retrieve=retrieve, os_cache=lambda n: tmp_path))
    p = datasets.fetch("round.stl")
    assert p == tmp_path / "meshes" / "trimesh-models" / "round.stl"
