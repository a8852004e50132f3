"""Pretrained results shipped with clfd-bench: finished leaderboards to explore without training.

A *bundle* is a compressed archive (``.tar.xz``) of a results directory exactly as a
leaderboard job writes it (``leaderboard.md/.csv/.json``, the figures, and
``runs/<dataset>/<method>/<run>/`` with ``results.json``, ``checkpoint.pt``, every
``predictions/after_task_{i}.npz``, ``sim_cache.json`` and ``train.log``; not ``videos/``,
which ``clfd-bench video`` makes), so ``clfd-bench video``, ``evaluate``, ``leaderboard`` and
``site`` accept the extracted folder as if it had been trained here::

    clfd-bench pretrained list
    clfd-bench pretrained get helloworld-fast --out results/helloworld-fast

:data:`BUNDLES` is the registry (name -> :class:`Bundle`). :func:`get` verifies the archive's
sha256 against the one pinned here, extracts it member by member into a temporary sibling of
the output folder (regular files and folders only, no member outside the folder) and renames
that into place, so a refused or interrupted ``get`` leaves nothing half-extracted. The
checkpoints inside are tensors and a JSON header (:mod:`clfd_bench.harness.checkpoint`,
loaded with ``weights_only=True``): a bundle never runs code.

Where archives come from: the ones shipped with the package live in its ``pretrained``
resource folder (:mod:`clfd_bench.resources`; in the wheel ``clfd_bench/_share/pretrained``).
A bundle too large for the wheel may instead name a release-asset ``url``; :func:`get`
downloads it once into ``~/.cache/clfd-bench/pretrained`` (``CLFD_CACHE_DIR`` overrides)
and verifies the same sha256. **That download path is not exercised by the tests or CI**
(they run offline); every bundle registered today is packaged.

Stale executions: each run's execution results name the simulator that produced them
(:func:`clfd_bench.execution.fingerprint.sim_fingerprint`). When the installed simulator
differs, the trajectory metrics, tables and figures still hold, ``clfd-bench video`` still
renders (it executes afresh), but the execution results are another simulator's:
:func:`stale_runs` lists them; ``clfd-bench evaluate RUN_DIR`` (or the bundle's leaderboard
command again) re-executes the saved predictions without training.

Making a bundle: ``python eval/make_pretrained.py RESULTS_DIR`` (deterministic archive: the
same results give the same sha256, which it prints for :data:`BUNDLES`).
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import tarfile
import tempfile
import uuid
from collections.abc import Iterable, Mapping
from pathlib import Path, PurePosixPath

from clfd_bench.io import fsync_dir, sha256_file
from clfd_bench.resources import resource_path
from clfd_bench.runs import find_runs

__all__ = [
    "BUNDLES",
    "Bundle",
    "PretrainedError",
    "archive_path",
    "build_bundle",
    "default_out",
    "describe",
    "extract_archive",
    "get",
    "list_bundles",
    "lookup",
    "make_archive",
    "method_runs",
    "stale_runs",
]


class PretrainedError(ValueError):
    """A bundle cannot be got (unknown name, failed checksum, unsafe archive, occupied
    output folder); the message says what to do."""


@dataclasses.dataclass(frozen=True)
class Bundle:
    """One shipped results directory.

    Attributes:
        name: what ``clfd-bench pretrained get`` takes.
        file: the archive's file name (in the package's ``pretrained`` folder, or the name
            it is cached under when downloaded).
        sha256: hex sha256 of the archive (printed by ``eval/make_pretrained.py``).
        description: one line for ``clfd-bench pretrained list``.
        dataset, profile: the leaderboard's dataset and hyperparameter profile.
        methods: the CL methods it holds a run of.
        made_with_version: the clfd-bench version that trained and executed it.
        size: the archive's size in bytes.
        url: a release asset to download the archive from when the package does not ship it
            (None: packaged). Not used by any bundle registered today.
    """

    name: str
    file: str
    sha256: str
    description: str
    dataset: str
    profile: str
    methods: tuple[str, ...]
    made_with_version: str
    size: int
    url: str | None = None


BUNDLES: dict[str, Bundle] = {
    b.name: b
    for b in (
        Bundle(
            name="helloworld-fast",
            file="helloworld-fast.tar.xz",
            sha256="5651f23f078cd4d02cd58ef3687b2a33acbe829e72a426dfaaf5f3aad903748a",
            description="the README's main job: HelloWorld (7 letters), all 7 methods, "
                        "`fast` profile, seed 0, order 0, executed on the simulated Panda",
            dataset="helloworld",
            profile="fast",
            methods=("sg", "ft", "rep", "si", "mas", "hn", "chn"),
            made_with_version="0.1.0",
            size=20559480,
        ),
    )
}
"""The registry: name -> :class:`Bundle`."""


def list_bundles() -> list[Bundle]:
    """Every registered bundle, by name."""
    return [BUNDLES[name] for name in sorted(BUNDLES)]


def lookup(name: str) -> Bundle:
    """The bundle called ``name``.

    Raises:
        PretrainedError: no such bundle (the message lists the valid names).
    """
    try:
        return BUNDLES[name]
    except KeyError:
        raise PretrainedError(f"unknown pretrained bundle {name!r}; valid: "
                              f"{', '.join(sorted(BUNDLES))}") from None


def default_out(name: str) -> Path:
    """Where ``get`` extracts when no folder is given: ``results/<name>``."""
    return Path("results") / name


def _cache_dir() -> Path:
    root = os.environ.get("CLFD_CACHE_DIR") or Path.home() / ".cache" / "clfd-bench"
    return Path(root) / "pretrained"


def archive_path(bundle: Bundle) -> Path:
    """The local archive of ``bundle``: the packaged file, or for a bundle with a ``url``
    its cached download (downloaded first if missing).

    Raises:
        PretrainedError: the package lacks the file and the bundle names no ``url``.
    """
    packaged = resource_path("pretrained", bundle.file)
    if packaged.is_file():
        return packaged
    if bundle.url is None:
        raise PretrainedError(f"the archive of bundle {bundle.name!r} ({packaged}) is missing: "
                              "the installation is incomplete; reinstall clfd-bench")
    cached = _cache_dir() / bundle.file
    if not cached.is_file():
        _download(bundle, cached)
    return cached


def _download(bundle: Bundle, dest: Path) -> None:
    """Fetches ``bundle.url`` into ``dest`` (temp file, checked, then renamed).

    NOT EXERCISED: no registered bundle has a url, and the tests and CI run offline. It is
    here so a future bundle can be a release asset rather than package data.
    """
    import urllib.request

    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = dest.with_name(f".{dest.name}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        with urllib.request.urlopen(bundle.url, timeout=60) as resp, open(tmp, "wb") as fh:
            shutil.copyfileobj(resp, fh)
        _check_sha256(tmp, bundle)
        os.replace(tmp, dest)
    except OSError as exc:
        raise PretrainedError(f"could not download bundle {bundle.name!r} from {bundle.url} "
                              f"({exc}); check the connection, or download it by hand to "
                              f"{dest}") from None
    finally:
        tmp.unlink(missing_ok=True)


def _check_sha256(path: Path, bundle: Bundle) -> None:
    got = sha256_file(path)
    if got != bundle.sha256:
        fix = (f"delete it to download it again ({bundle.url})" if bundle.url
               else "reinstall clfd-bench (pip install --force-reinstall clfd-bench)")
        raise PretrainedError(f"archive {path} failed its checksum (sha256 {got}, expected "
                              f"{bundle.sha256} for bundle {bundle.name!r}): it is corrupt "
                              f"or was modified; {fix}")


def _safe_members(tar: tarfile.TarFile, source: Path) -> list[tarfile.TarInfo]:
    """The archive's members, each a regular file or folder at a relative path that stays
    inside the output folder.

    Raises:
        PretrainedError: a member is a link, device or other special file, or its path is
            absolute or climbs out (``..``).
    """
    members = tar.getmembers()
    for m in members:
        path = PurePosixPath(m.name)
        if path.is_absolute() or ".." in path.parts or m.name.startswith(("/", "\\")):
            raise PretrainedError(f"archive {source} has a member outside its folder "
                                  f"({m.name!r}); refusing to extract it")
        if not (m.isfile() or m.isdir()):
            raise PretrainedError(f"archive {source} has a member that is not a regular file "
                                  f"or folder ({m.name!r}); refusing to extract it")
    return members


def _check_out(out: Path, force: bool) -> None:
    """Refuses an ``out`` folder that is a file, or exists and is not empty without
    ``force``."""
    if out.exists() and not out.is_dir():
        raise PretrainedError(f"--out {out} is a file; give a folder")
    if not force and out.exists() and any(out.iterdir()):
        raise PretrainedError(f"--out {out} exists and is not empty; choose another folder or "
                              "add --force to replace it")


def extract_archive(archive: str | os.PathLike[str], out_dir: str | os.PathLike[str],
                    bundle: Bundle, *, force: bool = False) -> Path:
    """Verifies ``archive`` against ``bundle.sha256`` and extracts it as ``out_dir``.

    Extraction goes to a temporary sibling of ``out_dir`` that is renamed into place at the
    end; with ``force`` an existing ``out_dir`` is renamed aside first and removed after.

    Raises:
        PretrainedError: checksum mismatch, unsafe member, or ``out_dir`` exists, is not
            empty and ``force`` is off. Nothing is left behind.
    """
    archive, out = Path(archive), Path(out_dir)
    _check_out(out, force)
    _check_sha256(archive, bundle)
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".get", dir=out.parent))
    try:
        with tarfile.open(archive, "r:*") as tar:
            for m in _safe_members(tar, archive):
                target = staging.joinpath(*PurePosixPath(m.name).parts)
                if m.isdir():
                    target.mkdir(parents=True, exist_ok=True)
                    continue
                target.parent.mkdir(parents=True, exist_ok=True)
                src = tar.extractfile(m)
                assert src is not None  # a regular file
                with src, open(target, "wb") as fh:
                    shutil.copyfileobj(src, fh)
        staging.chmod(0o755)
        _put_in_place(staging, out)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return out


def _put_in_place(staging: Path, out: Path) -> None:
    """Renames ``staging`` to ``out``; an existing ``out`` goes aside first, removed after."""
    aside = None
    if out.exists():
        aside = out.with_name(f".{out.name}.{uuid.uuid4().hex[:8]}.replaced")
        os.replace(out, aside)
    try:
        os.replace(staging, out)
    except BaseException:
        if aside is not None:
            os.replace(aside, out)
        raise
    fsync_dir(out.parent)
    if aside is not None:
        shutil.rmtree(aside, ignore_errors=True)


def get(name: str, out_dir: str | os.PathLike[str] | None = None, *,
        force: bool = False) -> Path:
    """Extracts bundle ``name`` into ``out_dir`` (default :func:`default_out`) and returns
    the results folder (``leaderboard.md``, ``runs/...``).

    Raises:
        PretrainedError: unknown name (lists the valid ones), checksum mismatch, unsafe
            archive, ``out_dir`` not empty without ``force``.
    """
    bundle = lookup(name)
    out = Path(out_dir) if out_dir is not None else default_out(name)
    _check_out(out, force)  # before any download or hashing
    return extract_archive(archive_path(bundle), out, bundle, force=force)


def stale_runs(results_dir: str | os.PathLike[str],
               fingerprint: str | None = None) -> list[tuple[Path, str]]:
    """The runs under ``results_dir`` whose execution results are not the installed
    simulator's (or missing), with the reason (:meth:`clfd_bench.runs.RunDir.status`).

    Args:
        fingerprint: the simulator to compare with (default: the installed one).
    """
    from clfd_bench.execution.fingerprint import sim_fingerprint

    current = fingerprint or sim_fingerprint()
    out = []
    for run in find_runs(results_dir):
        done = int((run.read_results() or {}).get("tasks_done") or 0)
        state = run.status(done, sim=True, fingerprint=current)
        if state.state != "done":
            out.append((run.path, state.reason))
    return out


def describe(bundles: Iterable[Bundle] | None = None) -> str:
    """The text of ``clfd-bench pretrained list``."""
    lines = []
    for b in bundles if bundles is not None else list_bundles():
        where = "packaged" if b.url is None else f"download: {b.url}"
        lines += [f"{b.name}  ({b.size / 1e6:.1f} MB, {where})",
                  f"    {b.description}",
                  f"    dataset {b.dataset}, profile {b.profile}, methods "
                  f"{', '.join(b.methods)}; made with clfd-bench {b.made_with_version}",
                  f"    sha256 {b.sha256}"]
    return "\n".join(lines)


def method_runs(results_dir: str | os.PathLike[str]) -> Mapping[str, Path]:
    """method name (the run's ``config.method``) -> its run folder, for the runs under
    ``results_dir`` (the first run of each method)."""
    out: dict[str, Path] = {}
    for run in find_runs(results_dir):
        method = str(((run.read_results() or {}).get("config") or {}).get("method") or "")
        if method:
            out.setdefault(method, run.path)
    return out


# ----------------------------------------------------------------------------- making bundles
#: mtime of every archive member: the archive's bytes depend on the files' contents only.
_EPOCH = 1_700_000_000
_XZ_PRESET = 9


def make_archive(folder: str | os.PathLike[str], archive: str | os.PathLike[str]) -> str:
    """Writes ``folder``'s files (not lock files, not hidden ones) into the ``.tar.xz``
    ``archive`` deterministically: members sorted by path, fixed mtime, owner and modes, so
    the same files always give the same bytes. Returns the archive's hex sha256."""
    import io
    import lzma

    folder, archive = Path(folder), Path(archive)
    files = sorted(
        (p for p in folder.rglob("*") if p.is_file()
         and not any(part.startswith(".") for part in p.relative_to(folder).parts)),
        key=lambda p: p.relative_to(folder).as_posix())
    dirs = sorted({q.relative_to(folder).as_posix() for p in files for q in p.parents
                   if q != folder and folder in q.parents})

    def info(name: str, is_dir: bool, size: int = 0) -> tarfile.TarInfo:
        ti = tarfile.TarInfo(name)
        ti.type = tarfile.DIRTYPE if is_dir else tarfile.REGTYPE
        ti.mode, ti.size, ti.mtime = (0o755 if is_dir else 0o644), size, _EPOCH
        ti.uid = ti.gid = 0
        ti.uname = ti.gname = ""
        return ti

    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w", format=tarfile.GNU_FORMAT) as tar:
        entries = [(d, None) for d in dirs] + [(p.relative_to(folder).as_posix(), p)
                                                for p in files]
        for name, path in sorted(entries, key=lambda e: e[0]):
            if path is None:
                tar.addfile(info(name, True))
            else:
                data = path.read_bytes()
                tar.addfile(info(name, False, len(data)), io.BytesIO(data))
    packed = lzma.compress(buf.getvalue(), format=lzma.FORMAT_XZ,
                           preset=_XZ_PRESET | lzma.PRESET_EXTREME)
    from clfd_bench.io import atomic_write_bytes

    atomic_write_bytes(archive, packed)
    return sha256_file(archive)


def build_bundle(results_dir: str | os.PathLike[str], archive: str | os.PathLike[str],
                 workers: int = 1) -> str:
    """Makes a bundle of a finished leaderboard folder (e.g. the main job's ``results/``)
    and returns its sha256.

    Copies each run's :meth:`~clfd_bench.runs.RunDir.portable_files` into a temporary
    folder (not ``videos/``: mp4s do not compress and ``clfd-bench video`` remakes them),
    writes the tables and figures there again with the leaderboard's own code (the same
    grid, read from ``leaderboard.json``; every run is done, so nothing is trained or
    executed), and archives that (:func:`make_archive`).

    Raises:
        PretrainedError: ``results_dir`` holds no leaderboard, includes runs from elsewhere,
            or a run is not done under the installed simulator (finish it first).
    """
    from clfd_bench.leaderboard.grid import GridOptions
    from clfd_bench.leaderboard.report import read_leaderboard
    from clfd_bench.leaderboard.runner import run_leaderboard

    src = Path(results_dir)
    try:
        meta = read_leaderboard(src)["meta"]
    except ValueError as exc:  # InputError: no or an unreadable leaderboard
        raise PretrainedError(str(exc)) from None
    if meta.get("included"):
        raise PretrainedError(f"{src}'s leaderboard includes runs from elsewhere (--include); "
                              "a bundle holds a grid's own runs only")
    runs = find_runs(src / "runs")
    stale = stale_runs(src / "runs")
    if not runs or stale:
        why = "; ".join(f"{p}: {r}" for p, r in stale) or "no runs"
        raise PretrainedError(f"{src} is not a finished leaderboard ({why}); run its "
                              "leaderboard command (or the main job) again first")
    with tempfile.TemporaryDirectory(prefix=".bundle.", dir=Path(archive).parent) as tmp:
        stage = Path(tmp) / "results"
        for run in runs:
            for path in run.portable_files():
                dest = stage / path.relative_to(src)
                dest.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(path, dest)
        result = run_leaderboard(
            dataset=meta["dataset"], methods=list(meta["methods"]), profile=meta["profile"],
            seeds=list(meta["seeds"]), orders=list(meta["orders"]), out=stage,
            options=GridOptions.from_meta(meta, workers=workers))
        if result.trained or result.failed:
            raise PretrainedError(f"re-tabulating {src} ran or failed runs "
                                  f"({[s.name for s in result.trained]}, "
                                  f"{[o.spec.name for o in result.failed]}); not a finished "
                                  "leaderboard")
        return make_archive(stage, archive)
