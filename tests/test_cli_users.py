"""``pneufdd users add``: the users file of the dashboard and the OPC UA server."""

from __future__ import annotations

import io
import stat
from pathlib import Path

import pytest

from pneufdd.cli.app import main
from pneufdd.monitor.credentials import Credentials, load_users


def _add(monkeypatch: pytest.MonkeyPatch, file: Path, name: str, password: str, *extra: str) -> int:
    monkeypatch.setattr("sys.stdin", io.StringIO(password + "\n"))
    return main(["users", "add", "--file", str(file), "--name", name, "--password-stdin", *extra])


def test_a_user_is_stored_hashed_and_can_log_in(monkeypatch, tmp_path, capsys) -> None:
    file = tmp_path / "users.toml"
    assert _add(monkeypatch, file, "ann", "correct horse") == 0
    assert _add(monkeypatch, file, "bob", "battery staple", "--role", "operator") == 0
    text = file.read_text()
    assert "correct horse" not in text
    assert "battery staple" not in text
    assert stat.S_IMODE(file.stat().st_mode) == 0o600
    users = load_users(file)
    assert {u.role for u in users.values()} == {"viewer", "operator"}
    creds = Credentials(users)
    assert creds.check_password("ann", "correct horse") is not None
    assert creds.check_password("ann", "battery staple") is None
    # a second add of the same name sets its role and password, the other user stays
    assert _add(monkeypatch, file, "ann", "new password", "--role", "operator") == 0
    creds = Credentials(load_users(file))
    assert creds.check_password("ann", "new password").role == "operator"
    assert creds.check_password("bob", "battery staple") is not None
    assert "correct horse" not in capsys.readouterr().out


@pytest.mark.parametrize(
    ("where", "words"),
    [
        ("missing/users.toml", "a file in an existing folder"),
        ("dangling", "a link that leads nowhere"),
        (".", "this is a folder"),
    ],
)
def test_a_users_file_that_cannot_be_written_is_refused_before_the_password(
    monkeypatch, tmp_path, capsys, where, words
) -> None:
    (tmp_path / "dangling").symlink_to(tmp_path / "nowhere")
    monkeypatch.chdir(tmp_path)
    # the password is too short too: the file is refused first, naming --file
    assert _add(monkeypatch, Path(where), "ann", "short") == 2
    err = capsys.readouterr().err
    assert "--file" in err
    assert words in err
    assert not (tmp_path / "nowhere").exists()


def test_a_short_password_or_a_damaged_file_leaves_the_file_as_it_was(
    monkeypatch, tmp_path, capsys
) -> None:
    file = tmp_path / "users.toml"
    assert _add(monkeypatch, file, "ann", "seven77") == 2
    assert "at least 8" in capsys.readouterr().err
    assert not file.exists()
    file.write_text("[users.ann]\nrole = 'admin'\n")
    assert _add(monkeypatch, file, "bob", "long enough") == 2
    assert "role" in capsys.readouterr().err
    assert file.read_text() == "[users.ann]\nrole = 'admin'\n"
