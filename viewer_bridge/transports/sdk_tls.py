"""TLS between the front and the foxglove-sdk's server behind it, with a certificate made per run.

The SDK's server listens on a loopback port of its own, and it checks no `Origin`: a web page
that found that port (a page can scan loopback ports) would read every topic through it. So the
SDK serves TLS only (`start_server(tls_cert=..., tls_key=...)`), with a certificate made here at
each start and never written anywhere: a browser asked for `wss://` refuses a certificate no
authority signed, with no prompt a page could get past, and `ws://` gets no HTTP answer at all.
The front alone knows the certificate, and checks that the server presents exactly it.

The key is Ed25519 (RFC 8032): made and used with the integer arithmetic written below, since
the standard library makes no keys; the SDK's rustls and OpenSSL both speak it. The certificate
is X.509 v3 (RFC 5280), self-signed, in DER written by hand (a handful of fixed fields); the key
goes to the SDK as PKCS#8 (RFC 5208, RFC 8410), the form it asks for.

The front's end of each connection is an `SdkLink`: the TLS state is an `ssl.SSLObject` over
memory buffers, used under a lock, so that the relay's two threads (one reading the SDK, one
writing the client's bytes to it) never use OpenSSL's state at once, which OpenSSL does not allow.
"""

from __future__ import annotations

import base64
import hashlib
import secrets
import socket
import ssl
import threading
import time
from dataclasses import dataclass

from viewer_bridge.errors import HandshakeError

TLS_CHUNK = 256 * 1024  # raw bytes read from the SDK's socket at a time (the relay's own CHUNK)

# --- Ed25519 (RFC 8032, section 5.1) ---------------------------------------------------------

_P = 2**255 - 19
_L = 2**252 + 27742317777372353535851937790883648493  # the order of the base point
_D = -121665 * pow(121666, _P - 2, _P) % _P
_BASE_X = 15112221349535400772501151409588531511454012693041857206046113283949847762202
_BASE_Y = 46316835694926478169428394003475163141307993866256225615783033603165251855960
_Point = tuple[int, int, int, int]  # extended coordinates X, Y, Z, T (x = X/Z, y = Y/Z, xy = T/Z)
_BASE: _Point = (_BASE_X, _BASE_Y, 1, _BASE_X * _BASE_Y % _P)


def _add(one: _Point, other: _Point) -> _Point:
    """Point addition on the twisted Edwards curve (RFC 8032, 5.1.4; it also doubles)."""
    x1, y1, z1, t1 = one
    x2, y2, z2, t2 = other
    a = (y1 - x1) * (y2 - x2) % _P
    b = (y1 + x1) * (y2 + x2) % _P
    c = 2 * _D * t1 * t2 % _P
    d = 2 * z1 * z2 % _P
    e, f, g, h = b - a, d - c, d + c, b + a
    return e * f % _P, g * h % _P, f * g % _P, e * h % _P


def _times(scalar: int, point: _Point) -> _Point:
    result: _Point = (0, 1, 1, 0)  # the neutral element
    while scalar:
        if scalar & 1:
            result = _add(result, point)
        point = _add(point, point)
        scalar >>= 1
    return result


def _encode(point: _Point) -> bytes:
    x, y, z, _ = point
    inverse = pow(z, _P - 2, _P)
    x, y = x * inverse % _P, y * inverse % _P
    return (y | (x & 1) << 255).to_bytes(32, "little")


def _sha512_int(*parts: bytes) -> int:
    return int.from_bytes(hashlib.sha512(b"".join(parts)).digest(), "little")


def _expand(seed: bytes) -> tuple[int, bytes, bytes]:
    """The secret scalar, the nonce prefix and the public key of a 32-byte seed."""
    digest = hashlib.sha512(seed).digest()
    scalar = int.from_bytes(digest[:32], "little")
    scalar &= (1 << 254) - 8  # clear the low 3 bits and bit 255
    scalar |= 1 << 254
    return scalar, digest[32:], _encode(_times(scalar, _BASE))


def _sign(seed: bytes, message: bytes) -> bytes:
    scalar, prefix, public = _expand(seed)
    nonce = _sha512_int(prefix, message) % _L
    commitment = _encode(_times(nonce, _BASE))
    challenge = _sha512_int(commitment, public, message) % _L
    return commitment + ((nonce + challenge * scalar) % _L).to_bytes(32, "little")


# --- DER (X.690), as far as a certificate needs it --------------------------------------------


def _der(tag: int, content: bytes) -> bytes:
    size = len(content)
    if size < 0x80:
        return bytes([tag, size]) + content
    length = size.to_bytes((size.bit_length() + 7) // 8, "big")
    return bytes([tag, 0x80 | len(length)]) + length + content


def _sequence(*parts: bytes) -> bytes:
    return _der(0x30, b"".join(parts))


_ED25519 = _sequence(bytes.fromhex("06032b6570"))  # AlgorithmIdentifier: OID 1.3.101.112, no parameters
_NAME = _sequence(_der(0x31, _sequence(bytes.fromhex("0603550403"), _der(0x0C, b"viewer-bridge SDK link"))))


def _utc_time(seconds: float) -> bytes:
    return _der(0x17, time.strftime("%y%m%d%H%M%SZ", time.gmtime(seconds)).encode())


def _pem(kind: str, der: bytes) -> bytes:
    text = base64.b64encode(der).decode()
    lines = [text[at : at + 64] for at in range(0, len(text), 64)]
    return "\n".join([f"-----BEGIN {kind}-----", *lines, f"-----END {kind}-----", ""]).encode()


@dataclass(frozen=True)
class SdkCertificate:
    """A self-signed certificate and its key, made for one run (`make`): PEM for the SDK, and the
    DER the front expects the server to present."""

    der: bytes
    cert_pem: bytes
    key_pem: bytes

    @classmethod
    def make(cls) -> SdkCertificate:
        seed = secrets.token_bytes(32)
        _, _, public = _expand(seed)
        now = time.time()
        serial = _der(
            0x02, bytes([1 + secrets.randbelow(127)]) + secrets.token_bytes(15)
        )  # positive, minimal
        tbs = _sequence(
            _der(0xA0, _der(0x02, b"\x02")),  # version: v3
            serial,
            _ED25519,
            _NAME,
            _sequence(_utc_time(now - 86400), _utc_time(now + 365 * 86400)),
            _NAME,
            _sequence(_ED25519, _der(0x03, b"\x00" + public)),
        )
        der = _sequence(tbs, _ED25519, _der(0x03, b"\x00" + _sign(seed, tbs)))
        key = _sequence(_der(0x02, b"\x00"), _ED25519, _der(0x04, _der(0x04, seed)))
        return cls(der, _pem("CERTIFICATE", der), _pem("PRIVATE KEY", key))

    def context(self) -> ssl.SSLContext:
        """The front's client context: no authority to check (the certificate is compared whole
        after the handshake, `SdkLink.open`), TLS 1.3."""
        context = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
        context.check_hostname = False
        context.verify_mode = ssl.CERT_NONE
        context.minimum_version = ssl.TLSVersion.TLSv1_3
        return context


class SdkLink:
    """The front's TLS connection to the SDK, with the socket methods the relay uses.

    Reads and writes may come from two threads: the TLS state is used under `_tls`, and the
    encrypted bytes a step makes are sent under `_sending`, taken before `_tls` is let go, so
    that records reach the socket in the order they were made. The socket itself is blocking,
    outside the lock: a thread waiting on it holds nothing."""

    def __init__(
        self, sock: socket.socket, tls: ssl.SSLObject, incoming: ssl.MemoryBIO, outgoing: ssl.MemoryBIO
    ):
        self.sock = sock
        self._tls = tls
        self._incoming = incoming
        self._outgoing = outgoing
        self._lock = threading.Lock()
        self._sending = threading.Lock()

    @classmethod
    def open(cls, port: int, certificate: SdkCertificate, seconds: float) -> SdkLink:
        """Connect to the SDK on 127.0.0.1:`port` and finish the TLS handshake within `seconds`;
        HandshakeError when the server presents another certificate, OSError when it is gone."""
        deadline = time.monotonic() + seconds
        sock = socket.create_connection(("127.0.0.1", port), timeout=seconds)
        incoming, outgoing = ssl.MemoryBIO(), ssl.MemoryBIO()
        link = cls(sock, certificate.context().wrap_bio(incoming, outgoing), incoming, outgoing)
        try:
            while True:
                try:
                    link._tls.do_handshake()
                    break
                except ssl.SSLWantReadError:
                    link._flush(link._outgoing.read())
                    sock.settimeout(max(0.001, deadline - time.monotonic()))
                    if not link._take(sock.recv(TLS_CHUNK)):
                        raise HandshakeError("the SDK's server closed during the TLS handshake") from None
            link._flush(link._outgoing.read())
            if link._tls.getpeercert(binary_form=True) != certificate.der:
                raise HandshakeError("the server behind the front presented another certificate than its own")
        except ssl.SSLError as error:  # before OSError, its base
            sock.close()
            raise HandshakeError(f"TLS to the SDK's server failed: {error}") from None
        except (HandshakeError, OSError):
            sock.close()
            raise
        return link

    def _take(self, raw: bytes) -> bool:
        """Feed encrypted bytes read from the socket; False at its end."""
        if not raw:
            self._incoming.write_eof()
            return False
        self._incoming.write(raw)
        return True

    def _flush(self, raw: bytes) -> None:
        if raw:
            self.sock.sendall(raw)

    def recv_into(self, buffer: bytearray | memoryview) -> int:
        """Plain bytes from the SDK into `buffer`: every whole record already come that fits
        (TLS gives one record, at most 16 kB, per read: a 100 kB message in one piece saves the
        relay six passes); 0 at the end of the stream."""
        view = memoryview(buffer)
        while True:
            with self._lock:
                count, ended = self._read_records(view)
                made = self._outgoing.read()  # what reading made the TLS state send (rare)
                if made:
                    self._sending.acquire()
            if made:
                try:
                    self._flush(made)
                finally:
                    self._sending.release()
            if count or ended:
                return count
            raw = self.sock.recv(TLS_CHUNK)
            with self._lock:
                self._take(raw)  # at its end, the next read says how it ended

    def _read_records(self, view: memoryview) -> tuple[int, bool]:
        """Decrypt into `view` what the bytes taken hold (under the lock); the count, and whether
        the stream has ended (cleanly or not)."""
        count = 0
        while count < len(view):
            try:
                got: int = self._tls.read(len(view) - count, view[count:])  # type: ignore[assignment]  # a count, given a buffer
            except ssl.SSLWantReadError:
                return count, False
            except (ssl.SSLZeroReturnError, ssl.SSLEOFError):
                return count, True
            except ssl.SSLError as error:
                raise OSError(f"TLS from the SDK's server: {error}") from None
            if not got:  # the server's close_notify: the end (given a buffer, a read returns a count)
                return count, True
            count += got
        return count, False

    def recv(self, size: int, /) -> bytes:
        buffer = bytearray(size)
        return bytes(buffer[: self.recv_into(buffer)])

    def sendall(self, data: bytes | bytearray | memoryview) -> None:
        with self._lock:
            try:
                self._tls.write(data)
            except ssl.SSLError as error:
                raise OSError(f"TLS to the SDK's server: {error}") from None
            raw = self._outgoing.read()
            self._sending.acquire()
        try:
            self._flush(raw)
        finally:
            self._sending.release()

    def shutdown(self, how: int) -> None:
        """Of the socket beneath (no close_notify: the SDK takes the end of the stream as the end)."""
        self.sock.shutdown(how)

    def close(self) -> None:
        self.sock.close()

    def settimeout(self, seconds: float | None) -> None:
        self.sock.settimeout(seconds)

    def setsockopt(self, level: int, option: int, value: int) -> None:
        self.sock.setsockopt(level, option, value)

    def getsockname(self) -> tuple[str, int]:
        name: tuple[str, int] = self.sock.getsockname()
        return name
