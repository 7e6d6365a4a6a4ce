"""The outcome of one solve of a problem file, and how it is written to disk.

A :class:`Result` holds per-sample status, iterations, residuals and timings
(every solve reports how it went), the arrays the problem produced, summary
metrics, and one row per compared method. :func:`write_result` writes
``result.json`` + ``arrays.npz`` + figures into ``OUT/<problem name>/``.

Writing is safe against interruption and concurrent writers:

* everything goes to a staging folder ``OUT/.NAME-tmp-HOST-PID-RANDOM/`` first
  (unique per process and call), which replaces ``OUT/NAME/`` only once it is
  complete: the old folder is renamed aside (``.NAME-old-HOST-PID-RANDOM``), the
  new one renamed in, the old one removed. The swap holds an exclusive
  ``fcntl.flock`` on ``OUT/.NAME.lock`` (removed when the swap is done), so
  writers of the same result in one folder never interleave; the last swap wins
  and the folder is always one complete result;
* a process killed while writing (even by SIGKILL) leaves its temporaries behind;
  the next write of that result removes the temporaries of this host whose
  process is gone (``os.kill(pid, 0)``);
* folders are created with the user's umask, like the files in them;
* an existing file or symlink at ``OUT/NAME`` is never replaced or deleted, and an
  ``--out`` that is a file, cannot be written or runs out of space is an
  :class:`OutputError` naming the folder (exit 2), with nothing half-written left.

Figures are drawn by the kind's :data:`FigureBuilder` from the arrays and the
summary alone, so :func:`redraw` can draw them again from a written folder.
"""

from __future__ import annotations

import fcntl
import json
import math
import os
import re
import secrets
import shutil
import socket
import stat
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping

import numpy as np

from optikin import __version__
from optikin.errors import OptikinError
from optikin.interrupt import removed_on_hard_stop
from optikin.status import SAMPLE_STATUSES, SOLVED
from optikin.tables import write_comparison

STATUSES = SAMPLE_STATUSES
"""Per-sample statuses a problem kind may report (:data:`optikin.status.SAMPLE_STATUSES`)."""
KIND_NAME = re.compile(r"[a-z][a-z0-9_]{0,63}")
"""What a problem kind's name looks like (checked before a result's kind is looked up)."""

Drawer = Callable[[Path], None]
"""Draws one figure into the PNG file it is given."""

FigureBuilder = Callable[[Mapping[str, np.ndarray], Mapping[str, Any]], dict[str, Drawer]]
"""``figures(arrays, summary) -> {name: drawer}``: a kind's figures from a result's arrays and its
JSON summary (:meth:`Result.summary`) alone. A figure whose arrays are missing is left out."""


@dataclass
class MethodRow:
    """One compared method (the solver under study or a baseline) and its summary metrics."""

    method: str
    role: str  # "solver", "baseline" or "variant" (another formulation solved by the same solver)
    metrics: dict[str, Any]


@dataclass
class Result:
    problem: str
    kind: str
    solver: str | None
    title: str
    arm: dict[str, Any]
    status: list[str]
    iterations: np.ndarray | None = None
    residuals: np.ndarray | None = None
    timings: dict[str, float] = field(default_factory=dict)
    metrics: dict[str, Any] = field(default_factory=dict)
    comparison: list[MethodRow] = field(default_factory=list)
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    criteria: dict[str, bool] = field(default_factory=dict)
    """Run-level success criteria the kind states (e.g. a tracking run converged), by name:
    met or not; a note says by how much one was missed."""
    provenance: dict[str, Any] = field(default_factory=dict)
    """What the run solved and where (:func:`optikin.provenance.provenance_of`), set by the runner."""
    setting: str | None = None
    """The size setting the run used (``options.setting`` of a kind that has one, e.g. ``small`` or ``full``),
    set by the runner; None for a kind without settings. A number quoted from one setting is not comparable
    with a run of another."""
    expect: dict[str, Any] | None = None
    """The verdict the problem file expects (``expect: {exit, because}``, :class:`optikin.spec.ExpectSpec`),
    set by the runner; None when the file states none."""

    def __post_init__(self) -> None:
        unknown = sorted(set(self.status) - set(STATUSES))
        if unknown:
            raise ValueError(f"unknown sample status {unknown}; allowed: {tuple(map(str, STATUSES))}")

    @property
    def samples(self) -> int:
        return len(self.status)

    def status_counts(self) -> dict[str, int]:
        return {s: self.status.count(s) for s in STATUSES if s in self.status}

    @property
    def succeeded(self) -> bool:
        """Every sample solved (:data:`SOLVED`) and every criterion met."""
        return all(s in SOLVED for s in self.status) and all(self.criteria.values())

    @property
    def exit_status(self) -> int:
        """The exit status of ``optikin solve`` for this result: 0 when it :attr:`succeeded`, else 1."""
        return 0 if self.succeeded else 1

    @property
    def as_expected(self) -> bool | None:
        """Whether :attr:`exit_status` is the problem file's ``expect.exit`` (None when it expects nothing)."""
        return None if self.expect is None else self.exit_status == self.expect.get("exit")

    def summary(self) -> dict[str, Any]:
        """Everything but the arrays and figures, as JSON-ready data."""
        failed = [i for i, s in enumerate(self.status) if s not in SOLVED]
        out = {
            "optikin": __version__,
            "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "problem": self.problem,
            "title": self.title,
            "kind": self.kind,
            "solver": self.solver,
            "setting": self.setting,
            "arm": self.arm,
            "samples": self.samples,
            "status_counts": self.status_counts(),
            "failed_samples": failed[:100],
            "criteria": self.criteria,
            "succeeded": self.succeeded,
            "expect": self.expect,
            "as_expected": self.as_expected,
            "timings": self.timings,
            "metrics": self.metrics,
            "comparison": [row.__dict__ for row in self.comparison],
            "notes": self.notes,
            "provenance": self.provenance,
        }
        if self.iterations is not None:
            out["iterations"] = _stats(self.iterations)
        if self.residuals is not None:
            out["residuals"] = _stats(self.residuals)
        return _json_ready(out)


def _stats(x: np.ndarray) -> dict[str, float]:
    x = np.asarray(x, dtype=float)
    finite = x[np.isfinite(x)]
    if finite.size == 0:
        return {"median": math.nan, "max": math.nan}
    return {"median": float(np.median(finite)), "max": float(finite.max()), "min": float(finite.min())}


def _json_ready(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _json_ready(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_ready(v) for v in x]
    if isinstance(x, np.ndarray):
        return _json_ready(x.tolist())
    if isinstance(x, (np.floating, float)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


class OutputError(OptikinError):
    """The output folder cannot take a result: names the folder, or the entry in the way."""


def check_output_folder(out_dir: Path, name: str) -> None:
    """Refuse, before a run starts, an output folder :func:`write_result` could not write into.

    Nothing is created: the folder is made when the result is written.

    Raises
    ------
    OutputError
        ``out_dir`` (or the nearest existing folder above it) is a file, or is not writable, or a file or
        symlink is at ``out_dir/<name>``.
    """
    out_dir = Path(out_dir)
    existing = out_dir
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        where = out_dir if existing == out_dir else existing
        raise OutputError(f"{where}: the output folder is not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise OutputError(f"{existing}: cannot write the result '{name}': permission denied")
    _refuse_non_folder(out_dir / name)


def write_result(
    result: Result,
    out_dir: Path,
    figures: bool = True,
    arrays: list[str] | None = None,
    figure_builder: FigureBuilder | None = None,
) -> Path:
    """Write ``result`` into ``out_dir/<problem>/``, replacing a previous one as a whole; returns that folder.

    Parameters
    ----------
    result:
        The result to write.
    out_dir:
        The output folder, created (with its parents) if missing.
    figures:
        Draw the figures of ``figure_builder``.
    arrays:
        Names of the arrays that go into ``arrays.npz`` (all when None).
    figure_builder:
        Draws the kind's figures from all of the result's arrays.

    Returns
    -------
    Path
        ``out_dir/<problem>``, holding one complete result.

    Raises
    ------
    OutputError
        ``out_dir`` is not a folder or cannot be written (read-only, full), or a file or
        symlink is at ``out_dir/<problem>``; nothing of this write is left behind.
    """
    out_dir = Path(out_dir)
    name = result.problem
    final = out_dir / name
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise OutputError(f"{out_dir}: the output folder is not a folder") from None
    except OSError as exc:
        raise OutputError(f"{out_dir}: cannot create the output folder: {_reason(exc)}") from None
    _refuse_non_folder(final)
    _remove_stale(out_dir, name)
    staging = out_dir / _temporary_name(name, "tmp")
    with removed_on_hard_stop(staging):
        _write_staged(result, staging, out_dir, final, figures, arrays, figure_builder)
    return final


def _write_staged(
    result: Result,
    staging: Path,
    out_dir: Path,
    final: Path,
    figures: bool,
    arrays: list[str] | None,
    figure_builder: FigureBuilder | None,
) -> None:
    """:func:`write_result`'s work: everything into ``staging``, then swapped in as ``final``."""
    name = result.problem
    try:
        staging.mkdir()
        kept = result.arrays if arrays is None else {k: v for k, v in result.arrays.items() if k in arrays}
        summary = result.summary()
        summary["arrays"] = {k: list(np.shape(v)) for k, v in kept.items()}
        summary["figures"] = []
        if kept:
            np.savez_compressed(staging / "arrays.npz", **kept)  # type: ignore[arg-type]
        if figures:
            drawers = figure_builder(result.arrays, summary) if figure_builder is not None else {}
            for figure, draw in drawers.items():
                draw(staging / f"{figure}.png")
                summary["figures"].append(f"{figure}.png")
        summary["tables"] = write_comparison(result.comparison, staging)
        (staging / "result.json").write_text(json.dumps(summary, indent=2) + "\n")
        with _locked(out_dir / f".{name}.lock"):
            _refuse_non_folder(final)
            old = _swap(staging, final)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except OSError as exc:
        shutil.rmtree(staging, ignore_errors=True)
        raise OutputError(f"{out_dir}: cannot write the result {name!r}: {_reason(exc)}") from None
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise


def _reason(exc: OSError) -> str:
    return exc.strerror or str(exc)


def _host() -> str:
    """This machine's name as it appears in temporary names (a shared folder may serve several)."""
    return re.sub(r"[^A-Za-z0-9.]", "_", socket.gethostname()) or "host"


def _temporary_name(name: str, role: str) -> str:
    """``.NAME-ROLE-HOST-PID-RANDOM``: unique per process and call, and tells whose it is."""
    return f".{name}-{role}-{_host()}-{os.getpid()}-{secrets.token_hex(4)}"


def process_alive(pid: int) -> bool:
    """Whether process ``pid`` of this host exists (one of another user counts)."""
    if pid <= 0:
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _remove_stale(out_dir: Path, name: str) -> None:
    """Remove the temporaries of result ``name`` left in ``out_dir`` by dead processes of this host."""
    pattern = re.compile(rf"\.{re.escape(name)}-(?:tmp|old)-{re.escape(_host())}-(\d+)-[0-9a-f]{{8}}")
    try:
        entries = list(out_dir.iterdir())
    except OSError:
        return
    for entry in entries:
        match = pattern.fullmatch(entry.name)
        if match is not None and not process_alive(int(match.group(1))):
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                entry.unlink(missing_ok=True)


def _refuse_non_folder(final: Path) -> None:
    """A file or symlink at ``final`` is the user's: name it rather than replace it."""
    try:
        mode = os.lstat(final).st_mode  # one look: another writer may be swapping the folder meanwhile
    except FileNotFoundError:
        return
    if not stat.S_ISDIR(mode):
        what = "a symlink" if stat.S_ISLNK(mode) else "a file"
        raise OutputError(f"{final}: is {what}, not a result folder; move it away or choose another --out")


@contextmanager
def _locked(path: Path) -> Iterator[None]:
    """Hold an exclusive ``flock`` on the lock file ``path``, removed again before it is released.

    A waiter that wakes up on a lock file already removed (or replaced) opens the current one again.
    """
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            held, current = os.fstat(fd), os.stat(path)
            if (held.st_dev, held.st_ino) == (current.st_dev, current.st_ino):
                break
        except FileNotFoundError:
            pass
        except BaseException:
            os.close(fd)
            raise
        os.close(fd)
    try:
        yield
    finally:
        path.unlink(missing_ok=True)
        os.close(fd)


def _swap(staging: Path, final: Path) -> Path | None:
    """Put ``staging`` at ``final``; a previous folder there is renamed aside first, and its new name returned
    (for the caller to remove once the lock is released)."""
    old = None
    if final.is_dir():
        old = final.with_name(_temporary_name(final.name, "old"))
        os.rename(final, old)
    try:
        os.rename(staging, final)
    except BaseException:
        if old is not None:
            os.rename(old, final)
        raise
    return old


ARRAY_KINDS = "biufcUS"
"""The numpy dtype kinds ``arrays.npz`` may hold (bool, integer, float, complex, text); never objects."""


def read_result(folder: Path) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The summary (``result.json``) and arrays (``arrays.npz``) of a written result.

    ``arrays.npz`` is read without unpickling anything (``allow_pickle=False``), and must hold exactly the
    arrays, with the shapes, that ``result.json`` records under ``arrays``; it may be absent only when that
    record is empty.

    Raises
    ------
    InputDataError
        Naming the folder and the file: not a result folder, ``result.json`` not a JSON object with a
        ``kind``, ``arrays.npz`` missing, not an ``.npz`` archive, truncated, holding object arrays, or
        holding arrays other than those recorded.
    """
    from optikin.errors import InputDataError

    folder = Path(folder)
    try:
        summary = json.loads((folder / "result.json").read_text())
    except OSError as exc:
        raise InputDataError(f"not a result folder: {exc.strerror or exc}", source=str(folder)) from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputDataError(f"result.json is not JSON: {exc}", source=str(folder)) from None
    if not isinstance(summary, dict) or "kind" not in summary:
        raise InputDataError("result.json names no problem kind", source=str(folder))
    recorded = summary.get("arrays")
    if recorded is not None and not (
        isinstance(recorded, dict)
        and all(isinstance(v, list) and all(type(n) is int for n in v) for v in recorded.values())
    ):
        raise InputDataError("arrays: expected a mapping of array name to shape", source=str(folder / "result.json"))
    npz = folder / "arrays.npz"
    if not npz.exists() and not npz.is_symlink():
        if recorded == {}:
            return summary, {}
        raise InputDataError("arrays.npz is missing: the result's arrays cannot be read", source=str(folder))
    arrays = _read_arrays(npz)
    if recorded is not None:
        for name in sorted(set(recorded) | set(arrays)):
            if name not in arrays:
                raise InputDataError(f"array {name!r} recorded in result.json is missing", source=str(npz))
            if name not in recorded:
                raise InputDataError(f"array {name!r} is not recorded in result.json", source=str(npz))
            if list(arrays[name].shape) != recorded[name]:
                raise InputDataError(
                    f"array {name!r} has shape {list(arrays[name].shape)}; result.json records {recorded[name]}",
                    source=str(npz),
                )
    return summary, arrays


def _read_arrays(npz: Path) -> dict[str, np.ndarray]:
    """Every array of ``npz``, read without unpickling (an object array is refused, never loaded)."""
    import zipfile
    import zlib

    from optikin.errors import InputDataError

    if not npz.is_file():
        raise InputDataError("is not a file", source=str(npz))
    if not zipfile.is_zipfile(npz):
        raise InputDataError("is not an .npz archive (a zip of .npy arrays)", source=str(npz))
    try:
        with np.load(npz, allow_pickle=False) as archive:
            arrays = {name: archive[name] for name in archive.files}
    except ValueError as exc:
        if "allow_pickle" in str(exc):
            raise InputDataError("holds object arrays, which are never loaded (no pickles)", source=str(npz)) from None
        raise InputDataError(f"cannot be read: {exc}", source=str(npz)) from None
    except (OSError, EOFError, KeyError, zipfile.BadZipFile, zlib.error, NotImplementedError) as exc:
        raise InputDataError(f"cannot be read (truncated or damaged): {exc}", source=str(npz)) from None
    for name, value in arrays.items():
        if value.dtype.kind not in ARRAY_KINDS:
            raise InputDataError(f"array {name!r} has dtype {value.dtype}: not numbers or text", source=str(npz))
    return arrays


def result_kind(folder: Path, summary: Mapping[str, Any]) -> Any:
    """The registered problem kind (:class:`optikin.problems.ProblemKind`) a written result names.

    The name must be a registered kind's or the name of a package of :mod:`optikin.problems`, checked
    before :func:`optikin.problems.load_kind` imports anything.

    Raises
    ------
    InputDataError
        ``result.json``'s ``kind`` is not a registered kind's name.
    """
    import pkgutil

    from optikin import problems
    from optikin.errors import InputDataError, UnknownNameError
    from optikin.problems import load_kind
    from optikin.registry import PROBLEM_KINDS

    name = summary.get("kind")
    unknown = InputDataError(f"unknown problem kind {name!r}", source=str(Path(folder) / "result.json"), field="kind")
    if not isinstance(name, str) or KIND_NAME.fullmatch(name) is None:
        raise unknown
    if name not in PROBLEM_KINDS and name not in {m.name for m in pkgutil.iter_modules(problems.__path__)}:
        raise unknown
    try:
        return load_kind(name)
    except UnknownNameError:
        raise unknown from None


def redraw(
    folder: Path, figure_builder: FigureBuilder, summary: Mapping[str, Any], arrays: Mapping[str, np.ndarray]
) -> list[Path]:
    """Draw a written result's figures again into ``folder``; each PNG replaces the old one atomically
    (drawn to a temporary name first, created with the user's umask).

    Raises
    ------
    InputDataError
        A figure cannot be drawn from ``arrays`` (arrays of shapes or values the kind never writes).
    """
    from optikin.errors import InputDataError

    written = []
    source = str(Path(folder) / "arrays.npz")
    try:
        drawers = figure_builder(arrays, summary)
    except (ValueError, IndexError, KeyError, TypeError) as exc:
        raise InputDataError(
            f"the arrays do not fit the kind's figures: {type(exc).__name__}: {exc}", source=source
        ) from None
    for name, draw in drawers.items():
        final = Path(folder) / f"{name}.png"
        temporary = Path(folder) / f"{_temporary_name(name, 'tmp')}.png"
        try:
            draw(temporary)
            os.replace(temporary, final)
        except (ValueError, IndexError, KeyError, TypeError) as exc:
            temporary.unlink(missing_ok=True)
            raise InputDataError(
                f"figure {name!r} cannot be drawn from these arrays: {type(exc).__name__}: {exc}", source=source
            ) from None
        except BaseException:
            temporary.unlink(missing_ok=True)
            raise
        written.append(final)
    return written
