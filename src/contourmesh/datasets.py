"""Sample data: a registry of the public files used by the tests and the comparisons.

Every entry names a file, the public repository it comes from at a fixed commit, the path there,
its sha256 and a licence note (see ``../shared/data/README.md`` for the provenance in full).
:func:`fetch` returns a local path:

1. from a mirror folder named by the environment variable ``CONTOURMESH_DATA`` (or ``mirror=``),
   laid out like the registry paths (``volumes/dgtal/Al.100.vol``, ...); the sha256 of a mirror
   file is checked too;
2. else downloaded on demand with pooch (imported lazily; ``pip install 'contourmesh[io]'``) into
   ``pooch.os_cache("contourmesh")`` and checked against the same sha256.

The ``.npz`` files are derived copies made for this project (arrays stored ``[x, y, z]``, see
:func:`contourmesh.io.read_volume`); they have no upstream URL and are available from a mirror
only.

Example
-------
>>> from contourmesh import datasets
>>> sorted(datasets.names())[:3]
['3holes.off', 'Al.100.npz', 'Al.100.vol']
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Dataset", "REGISTRY", "names", "info", "fetch", "sha256_of", "ENV_VAR"]

#: The environment variable naming a local mirror folder.
ENV_VAR = "CONTOURMESH_DATA"


@dataclass(frozen=True)
class Dataset:
    """One sample file: registry name, mirror-relative path, upstream URL (or None), sha256, licence."""

    name: str
    path: str
    url: str | None
    sha256: str
    license: str
    kind: str


# upstream repositories at the commits the files were taken from: (repo, commit, licence note)
_UPSTREAM = {
    "dgtal": ("DGtal-team/DGtal", "1574af90cd87", "DGtal repository: LGPL-3.0; the samples have no licence of their own"),
    "cgogn": ("cgogn/CGoGN_2", "5694b66c6763", "CGoGN_2 repository: LGPL-2.1; origin of the data not documented"),
    "libigl-tutorial-data": ("libigl/libigl-tutorial-data", "c1f9ede366d0",
                             "no LICENSE file; per its README Stanford models are for research use, others from "
                             "AIM@SHAPE, Cosmic Blobs, MPI or unknown"),
    "common-3d-test-models": ("alecjacobson/common-3d-test-models", "8a4f8642acaf",
                              "no LICENSE file; per-model sources in its README (spot: CC0, Keenan Crane)"),
    "trimesh-models": ("mikedh/trimesh", "a513c0e2cfa6", "trimesh repository: MIT; CAD parts of undocumented origin"),
    "dicompyler-core": ("dicompyler/dicompyler-core", "0d5729d7a241",
                        "dicompyler-core repository: BSD-3 (c) Aditya Panchal; anonymised clinical example, "
                        "no terms stated for the data"),
}

# where each mirror folder's files live in their upstream repository
_UPSTREAM_DIR = {
    ("volumes", "dgtal"): "examples/samples/",
    ("volumes", "cgogn"): "data/images/",
    ("meshes", "cgogn"): "data/meshes/off/",
    ("meshes", "dgtal"): "examples/samples/",
    ("meshes", "libigl-tutorial-data"): "",
    ("meshes", "common-3d-test-models"): "data/",
    ("meshes", "trimesh-models"): "models/",
    ("contours", "dicompyler-core"): "tests/testdata/example_data/",
}
_UPSTREAM_FILE = {"volumes/dgtal/lobsterCroped.vol": "tests/samples/lobsterCroped.vol"}

# (mirror-relative path, sha256): computed from the mirror and checked against manifest.json
_FILES = [
    ("contours/dicompyler-core/ct.0.dcm", "6eb080ed6a1f4c850706418582a0b40e6d10dc831c7f3e3fc7d7b0bdd404e542"),
    ("contours/dicompyler-core/rtss.dcm", "8fe3e3a20d1acf911f5c284dc40288d46f97acd43e4a63753cd6e3e1dac398cb"),
    ("contours/dicompyler-core/rtss_contours.npz", "34252f0a8a69d485206c0014fdb7637d3ba254a330dd5fd9c11515039058230d"),
    ("meshes/cgogn/aneurysm_3D.off", "02d20959f71729be9f3db84ac378c80e7af77425a0feac7ec150a6580c7fafcf"),
    ("meshes/cgogn/socket.off", "ba81663d077e520eea91ecbb417be241679004afd85576f98ed0ac938de395c9"),
    ("meshes/common-3d-test-models/cheburashka.obj", "b2ac59bc1112f1b3e086ac0285d9be7fdefef278a32151a79e650414b2244f3f"),
    ("meshes/common-3d-test-models/homer.obj", "b20b1391fd62964f65703d748514d86d747d1202d38e55e0f1addac7a5a10e8b"),
    ("meshes/common-3d-test-models/nefertiti.obj", "19e39748b145092878cc4faafd050505eb5991c5d3e497be2b4575673fa87968"),
    ("meshes/common-3d-test-models/rocker-arm.obj", "590257e6d01e689354821d807854306c3bfbb02d9cca73404d5a4924f105c287"),
    ("meshes/common-3d-test-models/spot.obj", "0738b5e8608fed74e5e8c7aa8dd0af97b4b74f9f6cbf7aac84cd7e40b2e44a75"),
    ("meshes/dgtal/lion-tri.obj", "cb655874e99b6c89ebf63e9b1a859f7dcd7b6c01c637e60941a27590df89cebb"),
    ("meshes/libigl-tutorial-data/3holes.off", "e8b1038cc70d11f393d8894ac08a5106293c50e95a5a60f0d5a8c8a7e884d106"),
    ("meshes/libigl-tutorial-data/arm.obj", "b7493c060434374a443501b2b5acb71288cbcaf6a3c42a52fcfc09f4dc5ef57c"),
    ("meshes/libigl-tutorial-data/armadillo.obj", "c007ebd11e541a2b1ab86a4c376653579281265f2c6c786a4a7bf47ba84d6879"),
    ("meshes/libigl-tutorial-data/bunny.off", "dda85ca6dc03ed83a0b754611d5c0b1a3c8ba5234e690479ac4a04063e6a7d4d"),
    ("meshes/libigl-tutorial-data/decimated-knight.off", "40aa1c53a81d6ad3b0f42023b1d78144488ff0a42afe3821e034d890ad9cffe2"),
    ("meshes/libigl-tutorial-data/decimated-max.obj", "e7489f9987a384f582c632ba19d8e6185e749909ef197215eb0c768597678532"),
    ("meshes/libigl-tutorial-data/elephant.obj", "f1038147fa61efd8b3213d119c682279ffea3cf06cc1713ae2a8ff81e68ba671"),
    ("meshes/libigl-tutorial-data/fandisk.off", "05bd799a78e7feece372b5b19787b7bc56c5f5e46888f998db23eaf30be2e443"),
    ("meshes/libigl-tutorial-data/fertility.off", "145fdfb007c8d5d09ba60943f14f4ddc9edd4327c7956fe379c624adeb59dc5b"),
    ("meshes/libigl-tutorial-data/horse_quad.obj", "f266409b006dd339125dab91c3ca6aefe7289a03c7cf5848b985fcb19ae3de93"),
    ("meshes/libigl-tutorial-data/screwdriver.off", "7acc128110cababcc62d4e472b23c5ee832863c46d79c1af6be8de6eda32c9a9"),
    ("meshes/trimesh-models/featuretype.STL", "c9946c4bb8034cd43522526a2f325200e2d2322a0c7258f848a81f00e418dab3"),
    ("meshes/trimesh-models/fixed_top.ply", "8cbe375e9070e65f7154cd1704ddb6f20a92641888cc6714b070e78e375886ff"),
    ("meshes/trimesh-models/idler_riser.STL", "8fb9237ab07cdd50b033ade13d79f14ba9ac68cefb0be07cb993a535a344b733"),
    ("meshes/trimesh-models/plate_holes.STL", "318f92206dd20b2cede5b70eb5e686d3627c6b157b91e9ed383314329dcff209"),
    ("meshes/trimesh-models/quadknot.obj", "03188bb460ac583e87048890de5a3382877d49e3aae8cb85ec6ea06b90d944a8"),
    ("meshes/trimesh-models/round.stl", "34e4be62bfc2df9d784e284b0d2e5702bb4cce34c1c778e77c2e2272908ca19c"),
    ("meshes/trimesh-models/torus.STL", "91441a7f60479bda93c59dd88134da3b4f33d1df71729fe71e1b2ae989974da3"),
    ("meshes/trimesh-models/unit_sphere.STL", "9d75b416e33887fd791945c2f1e42696ea1bf252a973b2db7c9626002e210d61"),
    ("volumes/cgogn/liver.inr.gz", "527cb35bee601652dc373e347c66de4b212d31b3973d548dac0d080577d1ed9d"),
    ("volumes/cgogn/liver.npz", "3d49f5314a5e063aa8ce9999c846f01575a57c9f388be1c43d36f927defc445f"),
    ("volumes/dgtal/Al.100.npz", "3f2b49f50b1a3618289c50d8c312b7dc841e987b7bcbc285ffd30db98cc78811"),
    ("volumes/dgtal/Al.100.vol", "6c7f06b3d4a36aace5ccf552182f39ffa23f83711783fe7f1a837508698c4947"),
    ("volumes/dgtal/bunny-128.npz", "5823af7d92d248550bfccf74cdffe5101d8dff722af101f95267296ec141efce"),
    ("volumes/dgtal/bunny-128.vol", "3a42ccee28d5e8b3c273444ac190ba6e05c35cbd9df5df77511c78e10f15874a"),
    ("volumes/dgtal/bunny-32.npz", "903499c9be33f8918d9c71c939a2b464df28e4fb7387eb104eb59674df12b494"),
    ("volumes/dgtal/bunny-32.vol", "8f7598922b74cdf095cee3adae46fc3b26e6730285dadd740a71b30d2080cb61"),
    ("volumes/dgtal/bunny-64.npz", "4ac330ebc490db8b9f9463a80361c5f0a651c06b00189466b3846e1410de5331"),
    ("volumes/dgtal/bunny-64.vol", "a2227cf64809f8b57defd316ce7be508c37a94e909c7a86abfc923369b63d9ff"),
    ("volumes/dgtal/cat10.npz", "e70e52a5708f68330b0bc1673af5bb5f3eb9eed73c15565613dc732cab5d57d6"),
    ("volumes/dgtal/cat10.vol", "511f2f645238cb1dba872aadebab1e4f63fcd3c6f3aa3a9284dbc987d017c12f"),
    ("volumes/dgtal/cat10b.npz", "67e801c2aa06294cf2c8cc4b83d07bb8340440cad49dc6e07134634b423aff0f"),
    ("volumes/dgtal/cat10b.vol", "0cc5fcb46a8a777595d826e840eab265e3ba4fefd5ca9bd247a06c34c471b468"),
    ("volumes/dgtal/dicomSample.npz", "9e26c298def6f4e823f4da54e880f6235ea9dd4f3dd5dece7dfc4985e83bae3c"),
    ("volumes/dgtal/lobster.npz", "1bf2a502741e37ceb21d4cac6d151e50e93e5117fc5470fd8c63f1213655b197"),
    ("volumes/dgtal/lobster.vol", "91bd8a37260c9e8bc532b1b66c0e625a1c76340efc926a606a0ee9545315b118"),
    ("volumes/dgtal/lobsterCroped.npz", "c0b14a2926c0a681e8f9ae2b091f6d8eb7b9ed1abf27a3a7da77f8d38dc041ac"),
    ("volumes/dgtal/lobsterCroped.vol", "2b61fab191253b3b510fe179436cf41f8ffc3b341256008a720e078a5cca8851"),
]


def _entry(path: str, sha: str) -> Dataset:
    top, sub, fname = path.split("/")
    repo, commit, lic = _UPSTREAM[sub]
    derived = fname.endswith(".npz")
    if derived:
        url = None
        lic = f"derived copy made for contourmesh from {repo}@{commit}; " + lic
    else:
        upath = _UPSTREAM_FILE.get(path, _UPSTREAM_DIR[(top, sub)] + fname)
        url = f"https://github.com/{repo}/raw/{commit}/{upath}"
    return Dataset(name=fname, path=path, url=url, sha256=sha, license=lic, kind={"volumes": "volume", "meshes": "mesh", "contours": "contour"}[top])


#: name -> Dataset.  Names are the file names (unique here); :func:`info` also accepts paths.
REGISTRY = {e.name: e for e in (_entry(p, h) for p, h in _FILES)}


def names() -> list:
    """All registry names."""
    return list(REGISTRY)


def info(name: str) -> Dataset:
    """The registry entry for a file name (``"bunny-64.vol"``) or mirror path (``"volumes/dgtal/bunny-64.vol"``)."""
    if not isinstance(name, str):
        raise TypeError(f"expected a dataset name (str); got {type(name).__name__}")
    if name in REGISTRY:
        return REGISTRY[name]
    for e in REGISTRY.values():
        if e.path == name:
            return e
    import difflib

    stem = name.lower().split(".")[0]
    close = difflib.get_close_matches(name, list(REGISTRY), n=5, cutoff=0.6)
    close += [n for n in REGISTRY if stem and n.lower().startswith(stem) and n not in close]
    hint = f"; did you mean {', '.join(close[:5])}?" if close else f"; known: {', '.join(sorted(REGISTRY))}"
    raise ValueError(f"unknown dataset {name!r}{hint}")


_VERIFIED: dict = {}


def sha256_of(path) -> str:
    """The hex sha256 of a file."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _verify(path: Path, entry: Dataset) -> Path:
    st = path.stat()
    key = (str(path), st.st_size, st.st_mtime_ns)
    if _VERIFIED.get(key) != entry.sha256:
        got = sha256_of(path)
        if got != entry.sha256:
            raise ValueError(f"{str(path)!r}: expected sha256 {entry.sha256} for dataset {entry.name!r}; found {got} "
                             "(a changed or corrupt copy)")
        _VERIFIED[key] = got
    return path


def fetch(name: str, *, mirror=None, download: bool = True) -> Path:
    """A local, checksum-verified path to a sample file.

    Parameters
    ----------
    name : str
        Registry name (file name such as ``"Al.100.vol"``) or mirror path.
    mirror : str or Path, optional
        Mirror folder; default: the environment variable ``CONTOURMESH_DATA``.
    download : bool
        Whether to download with pooch when the mirror does not have the file.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    ValueError
        Unknown name, or a file whose sha256 does not match.
    FileNotFoundError
        Not in the mirror and not downloadable (a derived file, or ``download=False``).
    ConnectionError
        The download failed (no network?); the message says how to use a mirror instead.
    """
    entry = info(name)
    folder = mirror if mirror is not None else os.environ.get(ENV_VAR)
    if folder:
        p = Path(folder).expanduser() / entry.path
        if p.is_file():
            return _verify(p, entry)
    where = f"the mirror {str(folder)!r}" if folder else f"a mirror (set {ENV_VAR} to a folder laid out like ../shared/data)"
    if entry.url is None:
        raise FileNotFoundError(f"dataset {entry.name!r} ({entry.path}) is a derived file with no upstream URL; "
                                f"it is only available from {where}")
    if not download:
        raise FileNotFoundError(f"dataset {entry.name!r} ({entry.path}) is not in {where} and download=False")
    try:
        import pooch
    except ImportError as exc:
        raise ImportError(f"downloading sample data needs pooch: `pip install 'contourmesh[io]'` "
                          f"(or set {ENV_VAR} to a local mirror): {exc}") from exc
    cache = Path(pooch.os_cache("contourmesh")) / Path(entry.path).parent
    try:
        got = pooch.retrieve(entry.url, known_hash=f"sha256:{entry.sha256}", fname=Path(entry.path).name,
                             path=cache, progressbar=False)
    except ValueError as exc:  # pooch's hash mismatch
        raise ValueError(f"download of {entry.url} does not match the registry sha256: {exc}") from exc
    except Exception as exc:  # requests' ConnectionError, HTTPError, timeouts, ...
        raise ConnectionError(f"could not download dataset {entry.name!r} from {entry.url} ({type(exc).__name__}: "
                              f"{exc}); without network, set {ENV_VAR} to a local mirror") from exc
    return Path(got)
