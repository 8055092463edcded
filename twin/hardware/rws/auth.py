"""The server side of a controller's authentication: HTTP digest (RFC 7616 with MD5 and
``qop=auth``, as an IRC5 asks for it) for RWS 1.0, basic for RWS 2.0, and the session cookies a
controller hands out once a client logged in (:data:`~twin.hardware.rws.protocol.SESSION_COOKIES`).
Standard library only."""

from __future__ import annotations

import base64
import binascii
import hashlib
import hmac
import re
import secrets
import threading
from http.cookies import SimpleCookie

from twin.hardware.rws.protocol import DIGEST_REALM, SESSION_COOKIES

_PARAM = re.compile(r'(\w+)=(?:"([^"]*)"|([^,\s]*))')


def _md5(text: str) -> str:
    return hashlib.md5(text.encode("utf-8")).hexdigest()


class Authenticator:
    """Checks each request's credentials or session, and logs sessions in and out.

    Args:
        version: 1 (digest) or 2 (basic).
        user, password: The one account.
    """

    def __init__(self, version: int, user: str, password: str) -> None:
        self.version, self.user, self.password = version, user, password
        self._nonces: set[str] = set()
        self._sessions: set[str] = set()
        self._lock = threading.Lock()

    def challenge(self) -> str:
        """The ``WWW-Authenticate`` header of a 401 answer."""
        if self.version == 2:
            return f'Basic realm="{DIGEST_REALM}"'
        nonce = secrets.token_hex(16)
        with self._lock:
            self._nonces.add(nonce)
        return (f'Digest realm="{DIGEST_REALM}", qop="auth", nonce="{nonce}", '
                f'opaque="{secrets.token_hex(8)}", algorithm=MD5')

    def _digest_ok(self, header: str, method: str, uri: str) -> bool:
        params = {m[1]: m[2] if m[2] is not None and m[2] != "" else m[3]
                  for m in _PARAM.finditer(header)}
        with self._lock:
            known = params.get("nonce") in self._nonces
        if not known or params.get("username") != self.user or params.get("uri") != uri \
                or params.get("realm") != DIGEST_REALM or params.get("qop") != "auth":
            return False
        ha1 = _md5(f"{self.user}:{DIGEST_REALM}:{self.password}")
        ha2 = _md5(f"{method}:{uri}")
        expected = _md5(f"{ha1}:{params['nonce']}:{params.get('nc', '')}:"
                        f"{params.get('cnonce', '')}:auth:{ha2}")
        return hmac.compare_digest(expected, params.get("response", ""))

    def _basic_ok(self, header: str) -> bool:
        try:
            user, _, password = base64.b64decode(header, validate=True).decode().partition(":")
        except (binascii.Error, UnicodeDecodeError):
            return False
        return hmac.compare_digest(user.encode(), self.user.encode()) and \
            hmac.compare_digest(password.encode(), self.password.encode())

    def session(self, cookie_header: str | None) -> str | None:
        """The logged-in session a request's cookies carry, or None."""
        if not cookie_header:
            return None
        cookies = SimpleCookie()
        cookies.load(cookie_header)
        token = cookies.get(SESSION_COOKIES[0])
        with self._lock:
            return token.value if token is not None and token.value in self._sessions else None

    def check(self, authorization: str | None, cookie_header: str | None, method: str,
              uri: str) -> tuple[bool, str | None]:
        """Whether a request may pass, and a new session token to hand out (None: it has one
        already, or it was refused)."""
        if self.session(cookie_header) is not None:
            return True, None
        scheme, _, value = (authorization or "").partition(" ")
        ok = self._digest_ok(value, method, uri) if scheme.lower() == "digest" \
            and self.version == 1 else scheme.lower() == "basic" and self.version == 2 \
            and self._basic_ok(value.strip())
        if not ok:
            return False, None
        token = secrets.token_hex(16)
        with self._lock:
            self._sessions.add(token)
        return True, token

    def logout(self, cookie_header: str | None) -> None:
        """End the session a request's cookies carry."""
        token = self.session(cookie_header)
        with self._lock:
            self._sessions.discard(token or "")


def session_cookies(token: str) -> list[str]:
    """The ``Set-Cookie`` headers of a new session."""
    return [f"{SESSION_COOKIES[0]}={token}; Path=/; HttpOnly",
            f"{SESSION_COOKIES[1]}={secrets.randbelow(10**9)}; Path=/"]
