"""API keys: generation, keyed hashing, and the caller's identity for every request.

A key is 256 random bits shown once; the database keeps only HMAC-SHA-256(server secret, key),
so a leaked table does not yield usable keys. Lookup is by that hash (an indexed equality) and
the stored hash is compared in constant time. In ``single-user`` mode no key is needed and
every request acts as ``TRAJOPT_DEFAULT_OWNER``.
"""

from __future__ import annotations

import hashlib
import hmac
import logging
import secrets
from dataclasses import dataclass

from app.errors import ApiError
from app.settings import MIN_SECRET_LENGTH, Settings, secret_problem
from app.storage import repository
from app.storage.models import ApiKey
from app.storage.session import Database

log = logging.getLogger(__name__)

KEY_PREFIX = "tj_"
API_KEY_HEADER = "X-API-Key"
MAX_KEY_LENGTH = 256


@dataclass(frozen=True)
class Principal:
    """Who is calling: the client owning the jobs, and the key used (``None``: single-user)."""

    client: str
    key_id: str | None = None


def generate_key() -> str:
    """A new random API key (``tj_`` + 43 URL-safe characters, 256 bits)."""
    return KEY_PREFIX + secrets.token_urlsafe(32)


def hash_key(key: str, secret: str) -> str:
    """The stored form of ``key``: hex HMAC-SHA-256 keyed with the server secret."""
    return hmac.new(secret.encode(), key.encode(), hashlib.sha256).hexdigest()


def require_secret(settings: Settings) -> str:
    """The server secret, or ``ValueError`` when it is missing or a well-known default."""
    secret = settings.api_key_secret.get_secret_value()
    problem = secret_problem(secret)
    if problem is not None:
        raise ValueError(
            f"TRAJOPT_API_KEY_SECRET {problem}; it must be a random value of at least "
            f"{MIN_SECRET_LENGTH} characters (e.g. `openssl rand -hex 32`), the same for the API "
            "and this command"
        )
    return secret


def create_key(database: Database, settings: Settings, client: str) -> tuple[ApiKey, str]:
    """Store a new key for ``client``; returns the row and the key itself (shown only once)."""
    client = client.strip()
    if not client or len(client) > 128 or not client.isprintable():
        raise ValueError("the client name must be 1..128 printable characters")
    secret = require_secret(settings)
    key = generate_key()
    with database.session() as session:
        row = repository.add_api_key(session, client, hash_key(key, secret), key[:10])
    log.info("API key %s created for client %s", row.id, client)
    return row, key


def _unauthorized(code: str, message: str) -> ApiError:
    return ApiError(401, code, message, headers={"WWW-Authenticate": "ApiKey"})


def authenticate(database: Database, settings: Settings, presented: str | None) -> Principal:
    """The principal of a request presenting ``presented`` in ``X-API-Key``; 401 otherwise."""
    if settings.auth_mode == "single-user":
        return Principal(settings.default_owner)
    if not presented:
        raise _unauthorized("missing_api_key", f"send an API key in the {API_KEY_HEADER} header")
    if len(presented) > MAX_KEY_LENGTH:
        raise _unauthorized("invalid_api_key", "the API key is not valid")
    digest = hash_key(presented, settings.api_key_secret.get_secret_value())
    with database.reader() as session:
        row = repository.find_api_key(session, digest)
    if row is None or not hmac.compare_digest(row.key_hash, digest):
        raise _unauthorized("invalid_api_key", "the API key is not valid")
    if row.revoked_at is not None:
        log.info("request with revoked API key %s of client %s", row.id, row.client)
        raise _unauthorized("invalid_api_key", "the API key is not valid")
    return Principal(row.client, row.id)
