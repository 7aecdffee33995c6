"""Login, sessions and CSRF tokens for the web interface.

Rules (issue 6, docs/web.md):

- Bound to a loopback address, pages and read-only API calls need no login. Anywhere else every
  request but the login page and static files needs a logged-in session.
- Changing anything (settings, motion, fault injection) needs a login whenever a password is set;
  a non-loopback bind always has one (given at start, or generated and printed once).
- Every state-changing request carries the session's CSRF token (header ``X-CSRF-Token``, or the
  form field ``csrf_token`` on the login form), also on loopback: a page on another site must not be
  able to move the fingers through a browser that happens to run on the gripper's PC.
- Sessions are random server-side ids (256 bits) in an HttpOnly, SameSite=Strict cookie, replaced
  on login; the cookie is Secure when served over HTTPS (``serve_web(ssl_certfile=...)``).
"""

from __future__ import annotations

import hmac
import ipaddress
import secrets
import time
from collections import OrderedDict, deque
from dataclasses import dataclass, field

COOKIE_NAME = "wsg_session"
CSRF_HEADER = "x-csrf-token"
CSRF_FIELD = "csrf_token"
MAX_SESSIONS = 1000  # beyond this the oldest unused anonymous session goes first: no memory exhaustion
SESSION_TTL_S = 8 * 3600.0
LOGIN_WINDOW_S = 60.0
LOGIN_MAX_FAILURES = 10  # per client address and window, then 429


def is_loopback_host(host: str) -> bool:
    """True for ``localhost``, 127.0.0.0/8 and ::1 (what "bound to loopback" means here)."""
    if host.lower() in ("localhost", "localhost.localdomain"):
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


@dataclass
class WebSession:
    """One browser session."""

    id: str
    csrf: str
    authenticated: bool = False
    created: float = field(default_factory=time.monotonic)
    last_seen: float = field(default_factory=time.monotonic)


class Auth:
    """Session store and the access rules above."""

    def __init__(self, *, loopback: bool, password: str | None) -> None:
        self.loopback = loopback
        self.password = password
        # Three tiers, evicted in this order when the store is full (issue 13 item 11): sessions
        # whose cookie never came back (what a flood of cookieless requests creates), anonymous
        # sessions in use (on loopback they hold the open page's CSRF token), logged-in sessions.
        self._new: OrderedDict[str, WebSession] = OrderedDict()
        self._used: OrderedDict[str, WebSession] = OrderedDict()
        self._logged_in: OrderedDict[str, WebSession] = OrderedDict()
        self._failures: dict[str, deque[float]] = {}

    # -- sessions -------------------------------------------------------------------------------
    def lookup(self, sid: str | None) -> WebSession | None:
        if not sid:
            return None
        tier = next((t for t in (self._logged_in, self._used, self._new) if sid in t), None)
        if tier is None:
            return None
        s = tier[sid]
        now = time.monotonic()
        if now - s.last_seen > SESSION_TTL_S:
            del tier[sid]
            return None
        s.last_seen = now
        if tier is self._new:  # the cookie came back: a browser that keeps it
            del tier[sid]
            self._used[sid] = s
        else:
            tier.move_to_end(sid)
        return s

    def create(self, *, authenticated: bool = False) -> WebSession:
        s = WebSession(id=secrets.token_urlsafe(32), csrf=secrets.token_urlsafe(32), authenticated=authenticated)
        (self._logged_in if authenticated else self._new)[s.id] = s
        while len(self) > MAX_SESSIONS:
            oldest = next(t for t in (self._new, self._used, self._logged_in) if t)
            oldest.popitem(last=False)
        return s

    def __len__(self) -> int:
        """Sessions held."""
        return len(self._new) + len(self._used) + len(self._logged_in)

    def drop(self, s: WebSession) -> None:
        for tier in (self._new, self._used, self._logged_in):
            tier.pop(s.id, None)

    # -- rules ----------------------------------------------------------------------------------
    def may_read(self, s: WebSession | None) -> bool:
        return self.loopback or (s is not None and s.authenticated)

    def may_write(self, s: WebSession | None) -> bool:
        if self.password is None:
            return True
        return s is not None and s.authenticated

    @property
    def login_possible(self) -> bool:
        return self.password is not None

    def csrf_ok(self, s: WebSession | None, token: str | None) -> bool:
        if s is None or not token:
            return False
        return hmac.compare_digest(s.csrf.encode(), token.encode())

    # -- login ----------------------------------------------------------------------------------
    def throttled(self, client: str) -> bool:
        """Too many failed logins from ``client`` within the last minute."""
        q = self._failures.get(client)
        if not q:
            return False
        now = time.monotonic()
        while q and now - q[0] > LOGIN_WINDOW_S:
            q.popleft()
        return len(q) >= LOGIN_MAX_FAILURES

    def login(self, s: WebSession, password: str, client: str) -> WebSession | None:
        """A fresh authenticated session (new id and CSRF token: no fixation), or None."""
        if self.password is None:
            return None
        if not hmac.compare_digest(self.password.encode(), password.encode()):
            self._failures.setdefault(client, deque()).append(time.monotonic())
            if len(self._failures) > MAX_SESSIONS:
                self._failures.pop(next(iter(self._failures)))
            return None
        self.drop(s)
        return self.create(authenticated=True)
