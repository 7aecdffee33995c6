"""Security rules of the web interface when bound to a non-loopback address (0.0.0.0 here).

Reading needs a login there; the login needs the password and the page's CSRF token; a session
cookie is HttpOnly/SameSite=Strict and replaced at login; changes need the CSRF token too.
"""

from __future__ import annotations

import contextlib
import json
import re
import subprocess
import time
from pathlib import Path
from typing import Any

import httpx
import pytest
import websockets.sync.client as ws_client
from websockets.exceptions import ConnectionClosed, InvalidStatus

from .conftest import ARTIFACTS, LiveSim
from .conftest import REMOTE_PASSWORD as PASSWORD


def _login_token(c: httpx.Client) -> str:
    page = c.get("/login").text
    m = re.search(r'name="csrf_token" value="([^"]+)"', page)
    assert m, page
    return m.group(1)


def login(c: httpx.Client, password: str = PASSWORD) -> httpx.Response:
    token = _login_token(c)
    return c.post("/login", data={"csrf_token": token, "password": password, "next": "/settings/motion"})


def test_everything_but_login_needs_a_session(remote: LiveSim) -> None:
    with httpx.Client(base_url=remote.url) as c:
        r = c.get("/diagnosis/fieldbus")
        assert r.status_code == 303 and r.headers["location"] == "/login?next=/diagnosis/fieldbus"
        assert c.get("/api/state").status_code == 401
        assert c.get("/api/settings").status_code == 401
        assert c.get("/docs/architecture.md").status_code == 303
        r = c.post("/api/move", json={"width": 10, "speed": 10})
        assert r.status_code == 401 and r.json()["detail"] == "login required"
        assert c.get("/login").status_code == 200
        assert c.get("/static/style.css").status_code == 200


def test_websocket_needs_a_session(remote: LiveSim) -> None:
    with pytest.raises(InvalidStatus) as info:
        ws_client.connect(remote.url.replace("http", "ws") + "/ws")
    assert info.value.response.status_code == 403


def test_login_refused_without_the_password_or_token(remote: LiveSim) -> None:
    with httpx.Client(base_url=remote.url) as c:
        r = login(c, "wrong")
        assert r.status_code == 401 and "Wrong password" in r.text
        r = c.post("/login", data={"password": PASSWORD})  # no CSRF token
        assert r.status_code == 403
        assert c.get("/api/state").status_code == 401


def test_login_gives_a_fresh_httponly_strict_cookie_then_csrf_guards_changes(remote: LiveSim) -> None:
    with httpx.Client(base_url=remote.url) as c:
        c.get("/login")
        anonymous = c.cookies.get("wsg_session")
        r = login(c)
        assert r.status_code == 303 and r.headers["location"] == "/settings/motion"
        cookie = r.headers["set-cookie"]
        assert "HttpOnly" in cookie and "SameSite=strict" in cookie and "Path=/" in cookie
        assert c.cookies.get("wsg_session") != anonymous  # no session fixation
        assert c.get("/api/state").status_code == 200
        r = c.post("/api/settings", json={"clamping_travel": 6.0})
        assert r.status_code == 403  # logged in, but no CSRF token
        token = c.get("/api/csrf").json()["token"]
        r = c.post("/api/settings", json={"clamping_travel": 6.0}, headers={"X-CSRF-Token": token})
        assert r.status_code == 200
        assert remote.call(lambda: remote.gripper.settings.clamping_travel) == 6.0
        r = c.post("/api/settings", json={"clamping_travel": -6.0}, headers={"X-CSRF-Token": token})
        assert r.status_code == 422  # validated server-side after login, too
        # log out: the old cookie is worthless
        old = c.cookies.get("wsg_session")
        assert c.post("/logout", data={"csrf_token": token}).status_code == 303
        with httpx.Client(base_url=remote.url, headers={"Cookie": f"wsg_session={old}"}) as replay:
            assert replay.get("/api/state").status_code == 401


def test_open_redirect_after_login_is_refused(remote: LiveSim) -> None:
    with httpx.Client(base_url=remote.url) as c:
        token = _login_token(c)
        r = c.post("/login", data={"csrf_token": token, "password": PASSWORD, "next": "//evil.example/"})
        assert r.status_code == 303 and r.headers["location"] == "/"


def test_repeated_wrong_passwords_are_throttled(tmp_path: Path) -> None:
    s = LiveSim(tmp_path, host="0.0.0.0", password=PASSWORD)
    try:
        with httpx.Client(base_url=s.url) as c:
            codes = [login(c, f"guess{i}").status_code for i in range(11)]
            assert codes[:10] == [401] * 10 and codes[10] == 429
            assert login(c).status_code == 429  # even the right one, for a minute
    finally:
        s.close()


def test_a_password_is_generated_and_printed_once(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    s = LiveSim(tmp_path, host="0.0.0.0")
    try:
        password = s.web.password
        assert password and len(password) >= 12
        err = capfd.readouterr().err
        assert err.count(password) == 1
        with httpx.Client(base_url=s.url) as c:
            assert login(c, password).status_code == 303
            assert c.get("/api/state").status_code == 200
    finally:
        s.close()


def test_loopback_with_password_reads_freely_but_changes_need_login(tmp_path: Path) -> None:
    s = LiveSim(tmp_path, password=PASSWORD)
    try:
        with httpx.Client(base_url=s.url) as c:
            assert c.get("/").status_code == 200 and c.get("/api/state").status_code == 200
            token = c.get("/api/csrf").json()["token"]
            r = c.post("/api/stop", headers={"X-CSRF-Token": token})
            assert r.status_code == 401
            login(c)
            token = c.get("/api/csrf").json()["token"]
            assert c.post("/api/stop", headers={"X-CSRF-Token": token}).status_code == 200
    finally:
        s.close()


@pytest.mark.browser
def test_browser_login_flow(remote: LiveSim, browser: Any) -> None:
    context = browser.new_context(viewport={"width": 1200, "height": 800}, bypass_csp=True)
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    try:
        page.goto(remote.url + "/diagnosis/log")
        assert page.url.startswith(remote.url + "/login")
        page.fill("#password", "not it")
        page.click("#login-submit")
        assert "Wrong password" in page.inner_text("#login-error")
        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(ARTIFACTS / "login-refused.png"))
        page.fill("#password", PASSWORD)
        page.click("#login-submit")
        page.wait_for_url(remote.url + "/diagnosis/log")
        assert page.inner_text("main h1") == "System Log"
        page.wait_for_function("window.WSG && WSG.updates > 2")  # the WebSocket is allowed now
        cookie = next(c for c in context.cookies() if c["name"] == "wsg_session")
        assert cookie["httpOnly"] and cookie["sameSite"] == "Strict"
        page.click("a[href='/']")
        page.click("#form-home button[type=submit]")
        page.wait_for_function("document.querySelector('#form-home output').innerText == 'E_CMD_PENDING'")
        page.click("#logout")
        page.wait_for_url(re.compile(r".*/login.*"))
        page.goto(remote.url + "/")
        assert "/login" in page.url
    finally:
        context.close()
    assert not errors


def test_https_session_cookie_is_secure(tmp_path: Path) -> None:
    key, cert = tmp_path / "key.pem", tmp_path / "cert.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", str(key), "-out",
                    str(cert), "-days", "1", "-subj", "/CN=127.0.0.1"], check=True, capture_output=True)
    s = LiveSim(tmp_path, host="0.0.0.0", password=PASSWORD, ssl_certfile=str(cert), ssl_keyfile=str(key))
    try:
        with httpx.Client(base_url=s.url.replace("http:", "https:"), verify=False) as c:
            r = login(c)
            assert r.status_code == 303
            assert "Secure" in r.headers["set-cookie"] and "HttpOnly" in r.headers["set-cookie"]
            assert c.get("/api/state").status_code == 200
    finally:
        s.close()


def test_live_clients_are_capped(tmp_path: Path) -> None:
    from pywsg.web.live import MAX_LIVE_CLIENTS

    s = LiveSim(tmp_path)
    url = s.url.replace("http", "ws") + "/ws"
    try:
        with contextlib.ExitStack() as stack:
            conns = [stack.enter_context(ws_client.connect(url)) for _ in range(MAX_LIVE_CLIENTS)]
            for ws in conns:
                ws.recv(timeout=2)
            with ws_client.connect(url) as extra, pytest.raises(ConnectionClosed) as info:
                extra.recv(timeout=2)
            assert info.value.rcvd is not None and info.value.rcvd.code == 1013
            conns[0].close()
            time.sleep(0.2)
            with ws_client.connect(url) as again:
                assert json.loads(again.recv(timeout=2))["type"] == "update"
    finally:
        s.close()
