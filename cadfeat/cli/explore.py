"""``cadfeat explore STUDY [--port N] [--no-browser] [--results results.json]``: the interactive explorer."""

from __future__ import annotations

import argparse
import socket
import sys
import time

from cadfeat.cli.command import Command
from cadfeat.cli.study import cache_arg
from cadfeat.errors import CadfeatError, Terminated


def _arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("study", help="study TOML file")
    parser.add_argument("--port", type=int, default=8765, help="port on 127.0.0.1 (default 8765; 0: any free port)")
    parser.add_argument("--no-browser", action="store_true", help="do not open the web browser")
    parser.add_argument("--results", default=None, metavar="JSON",
                        help="results.json of a run, for 'current vs optimum' (default: exports/<study name>/)")
    cache_arg(parser)


def explore(args: argparse.Namespace) -> int:
    """Explore a study in the browser: sliders -> measures and objectives along the path, 3-D and camera view.

    The page is served at once; the study is set up meanwhile (CAD builds, the design map, the objective scales —
    or read from the set-up cache when the same inputs were set up before) and the page shows its progress."""
    import webbrowser

    from cadfeat.explore import SessionLoader, serve  # lazy: keeps `cadfeat --help` fast

    if not 0 <= args.port <= 65535:
        raise CadfeatError(f"--port {args.port}: allowed: 0..65535 (0: any free port)")
    _check_port(args.port)  # a busy port is said before the set-up, not after
    print(f"cadfeat explore: loading {args.study}", file=sys.stderr, flush=True)
    loader = SessionLoader(args.study, args.results, cache=args.cache)  # (a bad study file fails here, at once)
    server = serve(loader.start(), args.port)
    print(f"cadfeat explore: {server.url}  (the page shows the study's set-up until it is ready; Ctrl-C to stop)",
          flush=True)
    failed = None
    try:
        if not args.no_browser:
            webbrowser.open(server.url)
        while not loader.done.wait(0.5):
            pass
        status = loader.status.to_dict()
        if status["state"] == "failed":
            failed = status["error"]
        else:
            print(f"cadfeat explore: study ready in {status['ready_s']:.1f} s ({_cache_note(status)})",
                  file=sys.stderr, flush=True)
            while True:
                time.sleep(0.5)
    except (KeyboardInterrupt, Terminated):
        pass
    finally:
        server.stop()
    if failed is not None:
        raise CadfeatError(f"explore: {failed}")
    print("cadfeat explore: stopped", file=sys.stderr, flush=True)
    return 0


def _cache_note(status: dict) -> str:
    if status["cache"] == "hit":
        saved = status.get("cache_saved_s")
        return "set-up read from the set-up cache" + (f"; it took {saved:.0f} s to make" if saved else "")
    if status["cache"] == "miss":
        return "set up and kept in the set-up cache for the next start"
    return "set-up cache off"


def _check_port(port: int) -> None:
    """``CadfeatError`` if 127.0.0.1:``port`` cannot be bound now (0: any port, always fine)."""
    from cadfeat.explore.server import HOST  # lazy: keeps `cadfeat --help` fast

    if port == 0:
        return
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((HOST, port))
        except OSError as exc:
            raise CadfeatError(f"explore: cannot listen on {HOST}:{port}: {exc.strerror or exc}; allowed: a free "
                               "port (--port N, 0 for any)") from None


COMMANDS = (
    Command("explore", _arguments, explore),
)
