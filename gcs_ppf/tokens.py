"""API bearer tokens: what the service stores of one (an id, the token's SHA-256, its scopes)
and how a new one is made.  Shared by the service (``api.auth`` checks them), the command
line (``gcs-ppf token``) and the tools that start a service of their own.

A token is 32 random bytes (``secrets.token_urlsafe``): with that much entropy a plain
SHA-256 is the right hash (a slow password hash protects guessable secrets; it adds nothing
here), and the service keeps only the hash.  Scopes: ``read`` (every GET and the live
streams) and ``command`` (every request that changes the service or the vehicles); a
``command`` token may read too.
"""

from __future__ import annotations

import hashlib
import json
import os
import secrets
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError

Scope = Literal["read", "command"]
SCOPES: tuple[Scope, ...] = ("read", "command")
TOKEN_BYTES = 32


class TokenEntry(BaseModel):
    """One token as the service stores it (never the token itself)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    id: str = Field(pattern=r"^[A-Za-z0-9_.-]{1,64}$", description="named in the audit log")
    sha256: str = Field(pattern=r"^[0-9a-f]{64}$", description="hex SHA-256 of the token")
    scopes: tuple[Scope, ...] = Field(min_length=1)

    def grants(self, scope: str) -> bool:
        return grants(self.scopes, scope)


def grants(scopes: tuple[Scope, ...], scope: str) -> bool:
    """Do ``scopes`` allow ``scope``: ``command`` includes ``read``."""
    return scope in scopes or (scope == "read" and "command" in scopes)


ENTRIES = TypeAdapter(list[TokenEntry])


def token_hash(token: str) -> str:
    return hashlib.sha256(token.encode()).hexdigest()


def new_token(token_id: str, scopes: tuple[Scope, ...] = SCOPES) -> tuple[str, TokenEntry]:
    """A fresh token and the entry that stores it."""
    token = secrets.token_urlsafe(TOKEN_BYTES)
    return token, TokenEntry(id=token_id, sha256=token_hash(token), scopes=scopes)


def entries_json(entries: list[TokenEntry]) -> str:
    """The JSON of ``GCS_PPF_TOKENS`` (and of a token file)."""
    return json.dumps([e.model_dump(mode="json") for e in entries])


def service_env(entries: list[TokenEntry]) -> dict[str, str]:
    """The environment that makes a ``gcs-ppf serve`` accept ``entries``."""
    return {"GCS_PPF_TOKENS": entries_json(entries)}


class TokenFileError(ValueError):
    """A token file that cannot be read, named with what is wrong."""


def load_token_file(path: Path) -> list[TokenEntry]:
    """The entries of a token file: a JSON list of ``{"id", "sha256", "scopes"}``."""
    try:
        entries = ENTRIES.validate_json(path.read_bytes())
    except OSError as exc:
        raise TokenFileError(f"token_file {path}: {exc.strerror or exc}") from None
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        raise TokenFileError(f"token_file {path}: [{where}]: {first['msg']}") from None
    ids = [e.id for e in entries]
    if len(set(ids)) != len(ids):
        raise TokenFileError(f"token_file {path}: duplicate token ids")
    return entries


def add_to_token_file(path: Path, entry: TokenEntry) -> None:
    """Add ``entry`` to the token file at ``path`` (created with mode 0600; an id it holds
    already is an error, the file left as it was)."""
    entries = load_token_file(path) if path.exists() else []
    if any(e.id == entry.id for e in entries):
        raise TokenFileError(f"token_file {path}: it has a token {entry.id!r} already")
    text = json.dumps([e.model_dump(mode="json") for e in [*entries, entry]], indent=1) + "\n"
    partial = path.with_name(path.name + ".partial")
    try:
        fd = os.open(partial, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(partial, path)
    except OSError as exc:
        raise TokenFileError(f"token_file {path}: {exc.strerror or exc}") from None
