"""A write that fails (a full disk, a file-size limit) names the file it was writing: the operating
system names none when ``write`` or ``fsync`` fails, and "No space left on device" alone does not
say which folder filled up.

The disk is filled for real in a child process: a file-size limit (``RLIMIT_FSIZE``, with
``SIGXFSZ`` ignored) makes the kernel refuse a write past it with ``EFBIG`` exactly where a full
disk refuses it with ``ENOSPC``, in the middle of a file and without a file name.
"""

from __future__ import annotations

import errno
import os
import subprocess
import sys
import textwrap

import pytest
from conftest import scenario_text

from dea_opt.files.atomic import atomic_path, write_atomic, write_data
from dea_opt.run.publish import MANIFEST_NAME
from dea_opt.sweep import journal


def full_disk(*_args, **_kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def test_a_failed_write_names_its_file_not_the_temporary_one(tmp_path):
    target = tmp_path / "runs" / "frames.csv"
    with pytest.raises(OSError) as caught:
        write_atomic(target, full_disk)
    assert caught.value.errno == errno.ENOSPC and caught.value.filename == str(target)
    assert str(target) in str(caught.value) and "No space left on device" in str(caught.value)
    assert not target.exists() and os.listdir(target.parent) == []  # the temporary file is gone

    def temporary_named(tmp):
        raise OSError(errno.EIO, os.strerror(errno.EIO), str(tmp))

    with pytest.raises(OSError) as caught:
        write_atomic(target, temporary_named)
    assert caught.value.filename == str(target)
    # an error about another file is left as it is; the error's class follows its number
    with pytest.raises(FileNotFoundError) as missing, atomic_path(target):
        open(tmp_path / "elsewhere.txt").close()  # noqa: SIM115 - the open is what fails
    assert missing.value.filename == str(tmp_path / "elsewhere.txt")
    with pytest.raises(PermissionError) as denied:
        write_atomic(target, lambda tmp: (_ for _ in ()).throw(OSError(errno.EACCES, "Permission denied")))
    assert denied.value.filename == str(target)
    write_data(target, "ok\n")  # and the folder is usable again
    assert target.read_text() == "ok\n"


def test_a_sweep_journal_that_cannot_grow_names_itself(tmp_path, monkeypatch):
    monkeypatch.setattr(journal.os, "write", full_disk)
    with pytest.raises(OSError) as caught:
        journal.append(tmp_path, {"case_id": "a", "status": "ok"})
    assert caught.value.filename == str(tmp_path / journal.JOURNAL_NAME)


SCENARIO = scenario_text(ny=40, law=None)

LIMITED = textwrap.dedent("""
    import resource, signal, sys
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG instead
    resource.setrlimit(resource.RLIMIT_FSIZE, (20000, 20000))  # bytes: the disk is full at 20 kB a file
    from dea_opt.cli import main
    sys.exit(main(sys.argv[1:]))
    """)


@pytest.mark.skipif(sys.platform == "win32", reason="no file-size limit (RLIMIT_FSIZE) on Windows")
def test_the_cli_names_the_file_a_full_disk_stopped(tmp_path):
    (tmp_path / "plate.toml").write_text(SCENARIO)
    out = tmp_path / "results"
    done = subprocess.run(
        [sys.executable, "-c", LIMITED, "run", str(tmp_path / "plate.toml"), "-o", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 2, done.stderr
    message = done.stderr.strip()
    assert message.startswith("dea-opt: error: File too large (") and "\n" not in message
    named = message.split("(", 1)[1].rstrip(")")
    assert named.startswith(str(out) + os.sep) and ".tmp" not in named  # the output file, in its folder
    assert "Traceback" not in done.stderr
    assert not (out / MANIFEST_NAME).exists()  # nothing published
