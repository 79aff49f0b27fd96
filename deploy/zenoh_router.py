"""Run a zenoh router from a JSON5 config with the eclipse-zenoh Python package (no zenohd needed).

Usage: python deploy/zenoh_router.py deploy/zenoh-router.json5
"""

import signal
import sys
import threading

import zenoh


def main(path: str) -> None:
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    with zenoh.open(zenoh.Config.from_file(path)):
        print(f"zenoh router running ({path})", flush=True)
        stop.wait()


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "deploy/zenoh-router.json5")
