"""Settings: the MAVLink signing key from the environment or a file, never shown."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest
from pydantic import ValidationError

from gcs_ppf.service.settings import Settings

PASSPHRASE = "correct horse battery staple"


def test_no_key_no_signing() -> None:
    assert Settings().signing_key_bytes is None


def test_key_from_the_environment_is_hashed_and_never_shown(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("GCS_PPF_SIGNING_KEY", PASSPHRASE)
    settings = Settings()
    assert settings.signing_key_bytes == hashlib.sha256(PASSPHRASE.encode()).digest()
    for shown in (repr(settings), str(settings), settings.model_dump_json()):
        assert PASSPHRASE not in shown
        assert settings.signing_key_bytes.hex() not in shown


def test_key_from_a_file_hex_or_passphrase(tmp_path: Path) -> None:
    hex_file = tmp_path / "key.hex"
    hex_file.write_text("ab" * 32 + "\n")
    assert Settings(signing_key_file=hex_file).signing_key_bytes == bytes([0xAB]) * 32
    phrase_file = tmp_path / "key.txt"
    phrase_file.write_text(PASSPHRASE)
    expected = hashlib.sha256(PASSPHRASE.encode()).digest()
    assert Settings(signing_key_file=phrase_file).signing_key_bytes == expected


@pytest.mark.parametrize(
    ("kwargs", "complaint"),
    [
        ({"signing_key_file": "/no/such/key"}, "signing_key_file: cannot read /no/such/key"),
        ({"signing_key": "  "}, "signing_key: signing key is empty"),
        ({"signing_key": PASSPHRASE, "signing_key_file": "/x"}, "set one of them, not both"),
    ],
)
def test_bad_key_settings_are_refused_by_name_without_quoting_the_key(
    kwargs: dict[str, str], complaint: str
) -> None:
    with pytest.raises(ValidationError) as info:
        Settings(**kwargs)  # type: ignore[arg-type]
    assert complaint in str(info.value)
    assert PASSPHRASE not in str(info.value)


def test_an_empty_key_file_is_refused(tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.write_text("\n")
    with pytest.raises(ValidationError, match="signing_key_file: signing key is empty"):
        Settings(signing_key_file=empty)
