"""Files streamed as a run goes, record by record, that a full disk cuts cleanly.

A run's log files (``agnav run --out``: trajectory.csv, localisation.csv, laser.alog, recording.rrd) grow for as
long as the robot drives, so they cannot be written whole at the end (:mod:`agnav_host.atomic`). A
:class:`StreamFile` takes whole records (a CSV line, a laser-log record, a piece of rerun's stream), buffers
them and writes them with ``os.write``; when the disk refuses bytes (ENOSPC, EIO, a file-size limit) it cuts the
file back to the end of its last whole record (``ftruncate``), removes it if not one record reached the disk,
says so once (a WARNING on the library's logger and ``on_error``), and takes no more records: the run goes on,
its log ends there. :meth:`StreamFile.close` returns a :class:`StreamedFile`: the path, the bytes on the disk
and whether the file stopped early, which the listing of a run's files gives as ``partial (N B)``.
"""

from __future__ import annotations

import errno
import logging
import os
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

__all__ = ["StreamFile", "StreamedFile"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class StreamedFile:
    """A streamed file as it is on the disk: ``size_bytes`` of whole records; ``partial``: it stopped early
    (``error`` says why); ``kept``: the file exists (a file that never got a whole record is removed)."""

    path: Path
    size_bytes: int
    records: int
    partial: bool = False
    error: str | None = None

    @property
    def kept(self) -> bool:
        return self.size_bytes > 0

    def listing(self) -> str:
        """How a run's list of written files shows it: the path, and ``partial (N B)`` for one cut short."""
        return f"{self.path} partial ({self.size_bytes} B)" if self.partial else str(self.path)


class StreamFile:
    """Writes whole records to ``path`` (created, or truncated when it exists; the OSError of the open goes to
    the caller: the folder cannot be written).

    :meth:`write` buffers a record and writes the buffer once it holds ``buffer_bytes`` or, with ``flush_s``,
    when ``flush_s`` of wall-clock time went by since the last write (a crash loses at most that); :meth:`flush`
    writes it at once. After the first write error the file ends on its last whole record, the error is said
    once (``what`` names the file in the message; ``on_error`` gets the same text as the log) and every later
    record is dropped (counted in ``dropped``). Safe to call from several threads."""

    def __init__(self, path: str | Path, what: str = "", buffer_bytes: int = 1 << 16, flush_s: float | None = 0.5,
                 on_error: Callable[[str], None] | None = None) -> None:
        self.path = Path(path)
        self.what = what or self.path.name
        self.buffer_bytes = buffer_bytes
        self.flush_s = flush_s
        self.on_error = on_error
        self.size_bytes = 0  # whole records on the disk
        self.records = 0  # whole records on the disk
        self.dropped = 0  # records refused after the error (or lost in the buffer it could not write)
        self.error: str | None = None
        self._buf = bytearray()
        self._ends: list[int] = []  # where each buffered record ends in ``_buf``
        self._lock = threading.Lock()
        self._closed = False
        self._last_flush = time.monotonic()
        self._fd: int | None = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_CLOEXEC", 0),
                                       0o666)

    @property
    def partial(self) -> bool:
        return self.error is not None

    def write(self, record: bytes) -> bool:
        """Take one whole record; False once the file has stopped (the record is dropped). ValueError after
        :meth:`close`."""
        with self._lock:
            if self._closed:
                raise ValueError(f"{self.path}: the file is closed")
            if self._fd is None:
                self.dropped += 1
                return False
            self._buf += record
            self._ends.append(len(self._buf))
            if len(self._buf) >= self.buffer_bytes or (
                    self.flush_s is not None and time.monotonic() - self._last_flush >= self.flush_s):
                self._flush_locked()
            return self._fd is not None

    def write_text(self, line: str) -> bool:
        """:meth:`write` of ``line`` in UTF-8 (a CSV row with its newline)."""
        return self.write(line.encode("utf-8"))

    def flush(self) -> None:
        with self._lock:
            if self._fd is not None:
                self._flush_locked()

    def _flush_locked(self) -> None:
        fd = self._fd
        assert fd is not None
        self._last_flush = time.monotonic()
        if not self._buf:
            return
        view = memoryview(bytes(self._buf))  # of a copy: the buffer stays free to clear whatever holds the view
        done = 0
        try:
            while done < len(view):
                n = os.write(fd, view[done:])
                if n <= 0:
                    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
                done += n
        except OSError as e:
            self._fail(e, done)
            return
        self.size_bytes += done
        self.records += len(self._ends)
        self._buf.clear()
        self._ends.clear()

    def _fail(self, e: OSError, done: int) -> None:
        """The first write error, ``done`` bytes of the buffer written: cut back to the last whole record, close,
        remove an empty file, say it once."""
        whole = [end for end in self._ends if end <= done]
        keep = self.size_bytes + (whole[-1] if whole else 0)
        self.records += len(whole)
        self.dropped += len(self._ends) - len(whole)
        self._buf.clear()
        self._ends.clear()
        fd, self._fd = self._fd, None
        assert fd is not None
        try:
            os.ftruncate(fd, keep)  # shrinking needs no free space
        except OSError:
            pass
        try:
            keep = os.fstat(fd).st_size
        except OSError:
            pass
        try:
            os.close(fd)
        except OSError:
            pass
        self.size_bytes = keep
        if keep == 0:
            try:
                self.path.unlink()
            except OSError:
                pass
        self.error = f"{e.strerror or e}"
        kept = f"partial ({keep} B), on its last whole record" if keep else "nothing reached the disk: no file left"
        msg = f"{self.what} {self.path}: {self.error}: the file stops here, {kept}; the run goes on"
        log.warning("%s", msg)
        if self.on_error is not None:
            try:
                self.on_error(msg)
            except Exception:  # noqa: BLE001  (the report must not end the run that it is about)
                log.debug("on_error of %s failed", self.path, exc_info=True)

    def fail(self, e: OSError) -> None:
        """Stop the file as a write error would (for a source whose bytes it cannot take whole): what is
        buffered is written first, the file ends on its last whole record."""
        with self._lock:
            if self._fd is not None:
                self._flush_locked()
            if self._fd is not None:
                self._fail(e, 0)

    def close(self) -> StreamedFile:
        """Write what is buffered and close (idempotent); a file without a byte is removed."""
        with self._lock:
            if not self._closed:
                self._closed = True
                if self._fd is not None:
                    self._flush_locked()
                fd, self._fd = self._fd, None
                if fd is not None:
                    try:
                        os.close(fd)
                    except OSError as e:  # a late EIO: the disk may hold less than was written
                        self.error = f"{e.strerror or e}"
                        log.warning("%s %s: %s when closing it: the file may end early", self.what, self.path,
                                    self.error)
                if self.size_bytes == 0:
                    self.path.unlink(missing_ok=True)
            return StreamedFile(self.path, self.size_bytes, self.records, self.partial, self.error)
