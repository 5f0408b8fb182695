"""Output files and folders of the commands: checked before a long job, the files of an earlier run cleared,
and a failure to write said in plain words (never a traceback)."""

from __future__ import annotations

import sys
from pathlib import Path

__all__ = ["OutputError", "check_output", "unusable_out_dir", "unwritable_file", "clear_earlier_outputs",
           "report_write_failure"]


class OutputError(Exception):
    """An output file that cannot be written (exit 1); the message names the path and the reason."""


def check_output(option: str, path: str | Path, suffixes: tuple[str, ...] = ()) -> Path:
    """Refuse an output path before any work: a wrong suffix is a usage error (ValueError, exit 2),
    a path that cannot be written an :class:`OutputError` (exit 1)."""
    p = Path(path)
    if suffixes and p.suffix.lower() not in suffixes:
        raise ValueError(f"{option} {path}: the file name must end in {' or '.join(suffixes)}")
    why = unwritable_file(p)
    if why:
        raise OutputError(f"{option} {path}: cannot write there: {why}")
    return p


def clear_earlier_outputs(command: str, out: str, patterns: tuple[str, ...], quiet: bool) -> str | None:
    """Remove the files matching ``patterns`` (globs: the files ``command`` writes) that an earlier run left
    in ``out``; other files are left alone. Why that failed, or None. Said on stderr unless ``quiet``: the
    names, or their count when there are more than eight."""
    old: list[Path] = []  # in the order of ``patterns``, then by name
    for pat in patterns:
        old += [p for p in sorted(Path(out).glob(pat)) if (p.is_file() or p.is_symlink()) and p not in old]
    for p in old:
        try:
            p.unlink()
        except OSError as e:
            return f"cannot remove {p.name} of an earlier run: {e.strerror or e}"
    if old and not quiet:
        what = ", ".join(p.name for p in old) if len(old) <= 8 else f"{len(old)} files"
        print(f"agnav {command}: --out {out}: removed the earlier run's {what}", file=sys.stderr)
    return None


def unusable_out_dir(out: str) -> str | None:
    """Why ``out`` cannot be the output folder (a file, a folder that cannot be made, or one that takes no new
    files), or None; made and tried here, before a long run, so that the run is not lost to a typo or to a
    read-only folder."""
    import tempfile

    p = Path(out)
    if p.exists() and not p.is_dir():
        return "is a file, not a folder"
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        return f"cannot create the folder: {e.strerror or e}"
    try:
        with tempfile.NamedTemporaryFile(dir=p, prefix=".agnav-write-check-"):
            pass
    except OSError as e:
        return f"cannot write in the folder: {e.strerror or e}"
    return None


def unwritable_file(p: Path) -> str | None:
    """Why the file ``p`` cannot be written (without leaving anything behind; missing folders count as made),
    or None if it can: checked before a long job, like :func:`unusable_out_dir` for a folder."""
    import tempfile

    if p.is_dir():
        return "it is a directory"
    parent = p.parent
    anc = parent
    while not anc.exists() and anc != anc.parent:
        anc = anc.parent
    if not anc.is_dir():
        return f"{anc} is not a directory"
    try:
        if anc == parent:
            existed = p.exists()
            with open(p, "ab"):
                pass
            if not existed:
                p.unlink()
        else:  # the missing folders will be made: this must be allowed where they start
            tempfile.TemporaryDirectory(dir=anc).cleanup()
    except OSError as e:
        if isinstance(e, FileNotFoundError) and parent.is_dir():
            return f"{parent} does not take new files ({e.strerror})"
        return e.strerror or str(e)
    return None


def report_write_failure(cmd: str, out: str, err: BaseException) -> int:
    """A run whose results could not all be written (disk full, read-only folder...): say so plainly and list
    what was kept, instead of a traceback. Returns the exit code, 1."""

    why = getattr(err, "strerror", None) or str(err)
    where = getattr(err, "filename", None)
    print(f"agnav {cmd}: could not write the results{f' ({where})' if where else ''}: {why}", file=sys.stderr)
    try:
        import shutil

        free = shutil.disk_usage(out).free
        if free < 1 << 20:
            print(f"agnav {cmd}: the disk holding {out} is full ({free} B free)", file=sys.stderr)
    except OSError:
        pass
    kept = sorted(p for p in Path(out).glob("*") if p.is_file() and p.stat().st_size > 0) if Path(out).is_dir() else []
    if kept:
        print(f"agnav {cmd}: kept {len(kept)} file(s): " + ", ".join(f"{p.name} ({p.stat().st_size} B)" for p in kept),
              file=sys.stderr)
    else:
        print(f"agnav {cmd}: nothing was written", file=sys.stderr)
    return 1
