"""Input errors and atomic output.

Every output file of the workflow is written to a temporary file in the target directory and
renamed into place, so that a failed job never leaves a half-written result. A job killed
outright (SIGKILL) may leave such a temporary file; :func:`remove_stale_temporaries` clears
them when the job is rerun. SIGTERM is turned into ``SystemExit`` by the command line
(:mod:`asphalt_nscd.cli`), which unwinds the writers; long loops also call
:func:`check_termination` so that a SIGTERM whose exception was swallowed inside a library
callback still stops the job at its next step.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from pathlib import Path
from typing import Iterator


_UMASK = os.umask(0)
os.umask(_UMASK)


class InputError(ValueError):
    """Bad input. The message names the file, the row or key, and what was expected."""


#: Signal number of a termination request received by this process (None: none).
_TERMINATION: dict[str, int | None] = {"signal": None}


def request_termination(signum: int) -> None:
    """Record a termination request (SIGTERM handler) and unwind: ``SystemExit(128 + signum)``."""
    _TERMINATION["signal"] = signum
    raise SystemExit(128 + signum)


def check_termination() -> None:
    """Raise ``SystemExit(128 + signum)`` if a termination request was received."""
    if _TERMINATION["signal"] is not None:
        raise SystemExit(128 + _TERMINATION["signal"])


def remove_stale_temporaries(path: str | os.PathLike) -> list[Path]:
    """Remove the temporary files :func:`atomic_path` left next to ``path`` when a writer was
    killed outright (SIGKILL, power loss). Returns the removed paths."""
    target = Path(path)
    stale = sorted(target.parent.glob(f".{target.name}.*.tmp")) if target.parent.is_dir() else []
    for tmp in stale:
        tmp.unlink(missing_ok=True)
    return stale


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` on success.

    On any exception the temporary file is removed and ``path`` is left untouched.
    Parent directories are created.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        os.chmod(tmp_path, 0o666 & ~_UMASK)  # mkstemp creates 0600; give the usual mode
        os.replace(tmp_path, target)
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise


def read_csv(path: str | os.PathLike, allow_empty: bool = False, **kwargs):
    """Read a CSV file into a pandas DataFrame.

    Raises
    ------
    InputError
        naming the file if it does not exist, is not a readable CSV file, or (unless
        ``allow_empty``) holds a header and no data row: a table a step wrote incompletely,
        with the command that rebuilds it.
    """
    import pandas as pd

    path = Path(path)
    try:
        frame = pd.read_csv(path, **kwargs)
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not a readable CSV file ({exc}); {rebuild_hint(path)}") from None
    if len(frame) == 0 and not allow_empty:
        raise InputError(f"{path}: no data rows after the header (an incomplete table); {rebuild_hint(path)}")
    return frame


def require_columns(frame, columns, where, expected: str | None = None) -> None:
    """Raise if ``frame`` (a table read from ``where``: a path or a name) lacks any of ``columns``:
    the one check of a table's required columns.

    Raises
    ------
    InputError
        "<where>: line 1 (header): missing column(s) [...]; expected <expected>" (default: the
        columns asked for), naming what was found too.
    """
    missing = [c for c in columns if c not in frame.columns]
    if missing:
        raise InputError(
            f"{where}: line 1 (header): missing column(s) {missing}; found {list(frame.columns)}; "
            f"expected {expected or list(columns)}"
        )


def checked(df, path, columns, positive=()):
    """``df`` (a table read from ``path``) with its numeric ``columns`` checked (present; finite
    numbers; ``positive``: > 0) and made floats, in place: the one check of a table's required
    columns.

    Raises
    ------
    InputError
        naming the file and the missing column(s), or the line and column of a bad value.
    """
    import numpy as np
    import pandas as pd

    require_columns(df, columns, path)
    for c in columns:
        v = pd.to_numeric(df[c], errors="coerce").to_numpy(float)
        bad = np.flatnonzero(~np.isfinite(v) | ((v <= 0) if c in positive else False))
        if bad.size:
            raise InputError(
                f"{path}: line {bad[0] + 2}, column '{c}': expected a finite number" + (" > 0" if c in positive else "")
            )
        df[c] = v
    return df


def content_sha256(path: str | os.PathLike) -> str:
    """SHA-256 (hex) of a file's bytes: the stamp that ties a result to the table it came from.

    Raises InputError naming the file if it cannot be read."""
    import hashlib

    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError as exc:
        raise InputError(f"{path}: cannot be read ({exc.strerror or exc})") from None


def rebuild_hint(path) -> str:
    """How a user rebuilds a file the workflow wrote (``results/...``), or checks their own.

    A missing file under ``results/`` is rebuilt by the workflow with the configuration that
    made the rest (``make run`` with the same ``CONFIG``, or ``make table`` with the same
    ``TABLE``), so the hint is to delete it and rerun, not a command tied to one configuration."""
    p = Path(path)
    if "results" in p.parts:
        return (
            "delete it and rerun the command that made it (make run, or make table, with the same "
            "CONFIG or TABLE): the workflow rebuilds it"
        )
    return "check the file"


def read_json(path: str | os.PathLike, what: str = "JSON file"):
    """Read a JSON file (any JSON value).

    Raises
    ------
    InputError
        naming the file: ``"<path>: cannot read the <what> (...)"`` if it cannot be opened,
        ``"<path>: not valid JSON (...)"`` if it does not parse.
    """
    import json

    try:
        with open(path, encoding="utf-8") as fh:
            return json.load(fh)
    except OSError as exc:
        raise InputError(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not valid JSON ({exc}); {rebuild_hint(path)}") from None


def read_json_lines(path: str | os.PathLike, what: str, keys=()) -> list[dict]:
    """The records of a JSON-lines checkpoint (one JSON object per line, appended as work ends),
    ``[]`` when the file does not exist. A last line cut short by a killed run is removed from
    the file (atomically; its work is done again).

    Raises
    ------
    InputError
        naming the file and line of any other line that is not a JSON object holding ``keys``
        (``what`` names the record), with the remedy: remove the file to restart.
    """
    path = Path(path)
    if not path.exists():
        return []
    lines = [x for x in path.read_text(encoding="utf-8").splitlines() if x.strip()]
    records = []
    for n, line in enumerate(lines):
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            if n < len(lines) - 1:
                raise InputError(f"{path}: line {n + 1} is not a {what} (JSON); remove the file to restart") from None
            with atomic_path(path) as tmp:
                tmp.write_text("".join(x + "\n" for x in lines[:-1]), encoding="utf-8")
            break
        if not isinstance(rec, dict) or any(k not in rec for k in keys):
            raise InputError(
                f"{path}: line {n + 1} is not a {what} (expected the keys {', '.join(keys)}); "
                "remove the file to restart"
            )
        records.append(rec)
    return records


def write_csv(frame, path: str | os.PathLike, **kwargs) -> None:
    """Write a pandas DataFrame to CSV atomically (no index unless asked)."""
    kwargs.setdefault("index", False)
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, **kwargs)


def write_json(obj, path: str | os.PathLike) -> None:
    """Write a JSON-serialisable object atomically, indented, with a trailing newline."""
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(obj, indent=2, default=_json_default) + "\n")


def write_text(text: str, path: str | os.PathLike) -> None:
    """Write text atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def savefig(fig, path: str | os.PathLike, **kwargs) -> None:
    """Save a matplotlib figure atomically (format from the suffix of ``path``)."""
    target = Path(path)
    kwargs.setdefault("dpi", 150)
    kwargs.setdefault("bbox_inches", "tight")
    with atomic_path(target) as tmp:
        fig.savefig(tmp, format=target.suffix.lstrip(".") or "png", **kwargs)


def _json_default(value):
    import numpy as np

    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def json_safe(obj):
    """Recursively turn NumPy scalars into Python ones, tuples into lists and non-finite
    floats into None (a JSON value any reader accepts)."""
    import numpy as np

    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


def publish_directory(files: list, root: str | os.PathLike, destination: str | os.PathLike, manifest: dict) -> Path:
    """Copy ``files`` (paths under ``root``) into ``destination``, keeping their paths relative
    to ``root``, with ``manifest.json`` (``manifest`` plus each file's SHA-256 under
    ``"files"``), and put the folder in place by renames: ``destination`` holds the previous
    complete set or this one, never a mix of two runs. A copy left by a killed publisher
    (``.<name>.new-*`` beside ``destination``) is removed first.

    Raises InputError naming a file that does not exist or is not under ``root``."""
    import shutil

    root, destination = Path(root), Path(destination)
    rels = []
    for f in files:
        p = Path(f)
        if not p.is_file():
            raise InputError(f"{p}: file not found (a result to publish in {destination})")
        try:
            rels.append(p.resolve().relative_to(root.resolve()))
        except ValueError:
            raise InputError(f"{p}: not under {root}, cannot be published in {destination}") from None
    destination.parent.mkdir(parents=True, exist_ok=True)
    for stale in destination.parent.glob(f".{destination.name}.new-*"):
        shutil.rmtree(stale, ignore_errors=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{destination.name}.new-", dir=destination.parent))
    try:
        for rel in dict.fromkeys(rels):
            (staging / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(root / rel, staging / rel)
        record = dict(manifest, files={rel.as_posix(): content_sha256(staging / rel) for rel in dict.fromkeys(rels)})
        (staging / "manifest.json").write_text(json.dumps(record, indent=2, default=_json_default) + "\n")
        os.chmod(staging, 0o777 & ~_UMASK)
        old = destination.with_name(f".{destination.name}.old-{os.getpid()}")
        if destination.exists():
            os.replace(destination, old)
        os.replace(staging, destination)
        shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return destination
