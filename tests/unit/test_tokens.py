"""API tokens (``gcs_ppf.tokens``), the link allow-list and loopback test (``api.auth``),
what the audit log keeps (``api.guard``), and the ``gcs-ppf token`` / ``serve`` commands."""

from __future__ import annotations

import json
import stat
from pathlib import Path

import pytest
from pydantic import ValidationError

from api.auth import is_loopback, link_allowed
from api.guard import body_record, outcome
from gcs_ppf.cli import main
from gcs_ppf.service.settings import Settings
from gcs_ppf.tokens import (
    TokenEntry,
    TokenFileError,
    add_to_token_file,
    load_token_file,
    new_token,
    token_hash,
)


def test_a_new_token_is_random_and_only_its_hash_is_stored() -> None:
    a, entry = new_token("ops")
    b, _ = new_token("ops")
    assert a != b
    assert len(a) >= 43  # 32 bytes, URL-safe base64
    assert entry.sha256 == token_hash(a) != token_hash(b)
    assert a not in entry.model_dump_json()
    assert entry.scopes == ("read", "command")


def test_command_includes_read_and_read_is_only_read() -> None:
    _, reader = new_token("r", ("read",))
    _, commander = new_token("c", ("command",))
    assert reader.grants("read")
    assert not reader.grants("command")
    assert commander.grants("read")
    assert commander.grants("command")


@pytest.mark.parametrize(
    ("content", "where"),
    [
        ("not json", "[]"),
        ('[{"id": "a b", "sha256": "' + "0" * 64 + '", "scopes": ["read"]}]', "[0.id]"),
        ('[{"id": "a", "sha256": "xyz", "scopes": ["read"]}]', "[0.sha256]"),
        ('[{"id": "a", "sha256": "' + "0" * 64 + '", "scopes": ["admin"]}]', "[0.scopes.0]"),
        ('[{"id": "a", "sha256": "' + "0" * 64 + '", "scopes": []}]', "[0.scopes]"),
    ],
)
def test_a_bad_token_file_is_an_error_naming_the_field(
    tmp_path: Path, content: str, where: str
) -> None:
    path = tmp_path / "tokens.json"
    path.write_text(content)
    with pytest.raises(TokenFileError) as err:
        load_token_file(path)
    assert str(path) in str(err.value)
    assert where in str(err.value)


def test_token_files_missing_or_with_duplicate_ids(tmp_path: Path) -> None:
    with pytest.raises(TokenFileError, match="No such file"):
        load_token_file(tmp_path / "none.json")
    _, entry = new_token("ops")
    path = tmp_path / "t.json"
    path.write_text(json.dumps([entry.model_dump(mode="json")] * 2))
    with pytest.raises(TokenFileError, match="duplicate token ids"):
        load_token_file(path)
    # a settings' token_file that cannot be read fails when the service builds its keyring
    with pytest.raises(TokenFileError):
        Settings(token_file=path).api_tokens()


def test_add_to_token_file_creates_it_private_and_refuses_a_known_id(tmp_path: Path) -> None:
    path = tmp_path / "tokens.json"
    _, a = new_token("a")
    _, b = new_token("b", ("read",))
    add_to_token_file(path, a)
    add_to_token_file(path, b)
    assert load_token_file(path) == [a, b]
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    before = path.read_text()
    with pytest.raises(TokenFileError, match="a token 'a' already"):
        add_to_token_file(path, new_token("a")[1])
    assert path.read_text() == before


def test_tokens_and_link_allow_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    _, entry = new_token("env")
    monkeypatch.setenv("GCS_PPF_TOKENS", json.dumps([entry.model_dump(mode="json")]))
    monkeypatch.setenv("GCS_PPF_LINK_ALLOW", '["10.0.0.0/24", "sitl"]')
    settings = Settings()
    assert settings.api_tokens() == [entry]
    assert settings.link_allow == ["10.0.0.0/24", "sitl"]
    monkeypatch.setenv("GCS_PPF_LINK_ALLOW", '["10.0.0.0/33"]')
    with pytest.raises(ValidationError, match="is not a network"):
        Settings()


def test_loopback_and_the_link_allow_list() -> None:
    for host in ("127.0.0.1", "127.8.9.10", "::1", "[::1]", "localhost", "LOCALHOST"):
        assert is_loopback(host), host
    for host in ("0.0.0.0", "::", "10.0.0.1", "localhost.example", "127.0.0.1.example"):
        assert not is_loopback(host), host
    allow = ["10.0.0.0/24", "SITL", "2001:db8::/32", "192.168.1.5"]
    assert link_allowed("127.0.0.1", [])
    assert link_allowed("10.0.0.200", allow)
    assert not link_allowed("10.0.1.1", allow)
    assert link_allowed("sitl", allow)
    assert not link_allowed("sitl.example", allow)
    assert link_allowed("2001:db8::7", allow)
    assert link_allowed("192.168.1.5", allow)
    assert not link_allowed("192.168.1.6", allow)
    assert not link_allowed("0.0.0.0", allow)
    # serial devices: terminals, or those named (or matched by a pattern) in the list
    for device in ("/dev/ttyUSB0", "/dev/ttyACM0", "/dev/pts/3", "/dev/serial/by-id/usb-SiK"):
        assert link_allowed(device, []), device
    for device in ("/dev/sda", "/dev/mem", "/etc/passwd", "/tmp/radio"):
        assert not link_allowed(device, allow), device
    assert link_allowed("/tmp/radio", ["/tmp/radio*"])
    assert link_allowed("/opt/radios/sik0", ["/opt/radios/*"])


def test_a_link_to_a_terminal_is_a_terminal(tmp_path: Path) -> None:
    """socat's ``link=`` names (and udev's) point at the terminal: judged by where they lead."""
    (tmp_path / "radio").symlink_to("/dev/pts/7")
    (tmp_path / "disk").symlink_to("/dev/sda")
    assert link_allowed(str(tmp_path / "radio"), [])
    assert not link_allowed(str(tmp_path / "disk"), [])


def test_what_the_audit_log_keeps_of_bodies_and_answers() -> None:
    assert body_record(b"") is None
    assert body_record(b'{"url": "tcp:127.0.0.1:9"}') == {"url": "tcp:127.0.0.1:9"}
    big = b"[" + b"1," * 2000 + b"1]"
    record = body_record(big)
    assert record["bytes"] == len(big)
    assert len(record["sha256"]) == 64
    assert body_record(b"{not json")["bytes"] == 9
    assert outcome(201, b"") == "ok"
    assert outcome(409, b'{"detail": "mission 3 is running"}') == "mission 3 is running"
    field_error = b'{"detail": [{"loc": ["body", "url"], "msg": "Field required"}]}'
    assert outcome(422, field_error) == "body.url: Field required"
    assert outcome(500, b"Internal Server Error") == "HTTP 500"


def test_the_token_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "tokens.json"
    assert main(["token", "ops", "--file", str(path)]) == 0
    out, err = capsys.readouterr()
    token = out.strip()
    assert "\n" not in token
    assert f"--token-file {path}" in err
    [entry] = load_token_file(path)
    assert entry == TokenEntry(id="ops", sha256=token_hash(token), scopes=("read", "command"))
    assert main(["token", "ops", "--file", str(path)]) == 2
    assert "already" in capsys.readouterr().err
    assert main(["token", "viewer", "--scope", "read"]) == 0
    out, err = capsys.readouterr()
    env = err.split("GCS_PPF_TOKENS='")[1].split("'")[0]
    assert json.loads(env) == [
        {"id": "viewer", "sha256": token_hash(out.strip()), "scopes": ["read"]}
    ]
    assert main(["token", "two words"]) == 2
    assert "id 'two words'" in capsys.readouterr().err


def test_serve_refuses_an_open_api_off_loopback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = str(tmp_path / "gcs.db")
    assert main(["serve", "--host", "0.0.0.0", "--db", db]) == 2
    err = capsys.readouterr().err
    assert "host 0.0.0.0: no API token is configured" in err
    assert "gcs-ppf token NAME --file tokens.json" in err
    assert "--token-file tokens.json" in err
    assert main(["serve", "--db", db, "--token-file", str(tmp_path / "none.json")]) == 2
    assert "none.json" in capsys.readouterr().err
