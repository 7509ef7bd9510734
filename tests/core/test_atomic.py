import os
import stat

from bedstruct import _atomic
from bedstruct._atomic import atomic_path


def _mode(p):
    return stat.S_IMODE(os.stat(p).st_mode)


def test_new_file_gets_the_umask_mode_not_mkstemps_0600(tmp_path):
    target = tmp_path / "report.json"
    with atomic_path(target) as tmp:
        open(tmp, "w").write("{}")
    assert _mode(target) == 0o666 & ~_atomic._UMASK
    # and a file written by plain open() in the same process agrees
    plain = tmp_path / "plain.json"
    plain.write_text("{}")
    assert _mode(target) == _mode(plain)


def test_replacing_a_file_keeps_its_permissions(tmp_path):
    target = tmp_path / "results.json"
    target.write_text("old")
    os.chmod(target, 0o640)
    with atomic_path(target) as tmp:
        open(tmp, "w").write("new")
    assert target.read_text() == "new" and _mode(target) == 0o640
