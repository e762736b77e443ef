#!/usr/bin/env python3
"""A small HTTP/1.1 server for one file with byte ranges and injected faults, for the range
fetcher's tests (io/range_fetch.h). Keep-alive, one range per request (Range: bytes=A-B).

  fake_range_server.py --file F [--port P] [--path /db.bin] [faults...]

Prints "http://127.0.0.1:PORT/PATH" on the first line of stdout once it listens (--port 0 picks
a free port). Faults (counted over the whole run, per distinct range where it says so):
  --corrupt-first N      the first N responses for each range have one byte flipped
  --close-mid-body N     the first N responses send the head and half the body, then close
  --status-first N:CODE  the first N requests get HTTP CODE (e.g. 503) with a short body
  --delay-ms D           wait D ms before each response
  --close-every N        every N-th range response says "Connection: close" and closes
  --ignore-range         answer 200 with the whole file (a server without range support)
  --content-length N     206 responses say Content-Length: N (whatever the body), then close
Stops on SIGTERM or SIGINT.
"""
import argparse
import http.server
import os
import re
import signal
import socket
import socketserver
import sys
import threading
import time

RANGE_RE = re.compile(r"^bytes=(\d+)-(\d+)$")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--file", required=True)
    ap.add_argument("--port", type=int, default=0)
    ap.add_argument("--path", default=None, help="URL path (default: /BASENAME)")
    ap.add_argument("--corrupt-first", type=int, default=0)
    ap.add_argument("--close-mid-body", type=int, default=0)
    ap.add_argument("--status-first", default="")
    ap.add_argument("--delay-ms", type=float, default=0.0)
    ap.add_argument("--close-every", type=int, default=0)
    ap.add_argument("--ignore-range", action="store_true")
    ap.add_argument("--content-length", type=int, default=-1)
    a = ap.parse_args()

    with open(a.file, "rb") as f:
        data = f.read()
    path = a.path or "/" + os.path.basename(a.file)
    status_n, status_code = 0, 0
    if a.status_first:
        m = re.match(r"^(\d+):(\d{3})$", a.status_first)
        if not m:
            sys.exit(f"fake_range_server: --status-first {a.status_first!r}: want N:CODE, e.g. 2:503")
        status_n, status_code = int(m.group(1)), int(m.group(2))

    lock = threading.Lock()
    state = {"corrupt": {}, "closes": 0, "statuses": 0, "responses": 0}

    class Handler(http.server.BaseHTTPRequestHandler):
        protocol_version = "HTTP/1.1"

        def log_message(self, fmt, *args):  # quiet
            pass

        def send_small(self, code, text, extra=None):
            body = text.encode()
            self.send_response(code)
            self.send_header("Content-Type", "text/plain")
            self.send_header("Content-Length", str(len(body)))
            for k, v in (extra or {}).items():
                self.send_header(k, v)
            self.end_headers()
            self.wfile.write(body)

        def do_GET(self):
            if a.delay_ms > 0:
                time.sleep(a.delay_ms / 1000.0)
            with lock:
                if state["statuses"] < status_n:
                    state["statuses"] += 1
                    code = status_code
                else:
                    code = 0
            if code:
                self.send_small(code, f"injected status {code}\n")
                return
            if self.path != path:
                self.send_small(404, "not found\n")
                return
            if a.ignore_range:
                self.send_response(200)
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)
                return
            m = RANGE_RE.match(self.headers.get("Range", ""))
            if not m:
                self.send_small(400, "want Range: bytes=A-B\n")
                return
            first, last = int(m.group(1)), int(m.group(2))
            if first > last or first >= len(data):
                self.send_small(416, "range not satisfiable\n", {"Content-Range": f"bytes */{len(data)}"})
                return
            last = min(last, len(data) - 1)
            body = bytearray(data[first:last + 1])
            close_mid = False
            close_after = False
            with lock:
                state["responses"] += 1
                if a.close_every > 0 and state["responses"] % a.close_every == 0:
                    close_after = True
                n = state["corrupt"].get((first, last), 0)
                if n < a.corrupt_first:
                    state["corrupt"][(first, last)] = n + 1
                    body[len(body) // 2] ^= 0xFF
                if state["closes"] < a.close_mid_body:
                    state["closes"] += 1
                    close_mid = True
            self.send_response(206)
            self.send_header("Content-Range", f"bytes {first}-{last}/{len(data)}")
            self.send_header("Content-Length", str(len(body) if a.content_length < 0 else a.content_length))
            if a.content_length >= 0:
                close_after = True
            if close_after:
                self.send_header("Connection", "close")
                self.close_connection = True
            self.end_headers()
            if close_mid:
                self.wfile.write(bytes(body[: len(body) // 2]))
                self.wfile.flush()
                self.close_connection = True
                return
            self.wfile.write(bytes(body))

    class Server(socketserver.ThreadingMixIn, http.server.HTTPServer):
        daemon_threads = True
        allow_reuse_address = True

        def handle_error(self, request, client_address):
            # A client that closes while a long body is written (it refused the head) is normal.
            if isinstance(sys.exc_info()[1], (BrokenPipeError, ConnectionResetError)):
                return
            super().handle_error(request, client_address)

        def shutdown_request(self, request):
            # Lingering close, as nginx does: closing a socket with pipelined requests still
            # unread makes the kernel send RST, which may discard the last response before the
            # client has read it. Send FIN, read what the client still sends, then close.
            try:
                request.shutdown(socket.SHUT_WR)
                request.settimeout(0.5)
                while request.recv(65536):
                    pass
            except OSError:
                pass
            self.close_request(request)

    srv = Server(("127.0.0.1", a.port), Handler)
    signal.signal(signal.SIGTERM, lambda *_: os._exit(0))
    print(f"http://127.0.0.1:{srv.server_address[1]}{path}", flush=True)
    try:
        srv.serve_forever(poll_interval=0.05)
    except KeyboardInterrupt:
        pass


if __name__ == "__main__":
    main()
