"""Helpers of the scripts that run afr's nodes on loopback (wall_scale.py, liveness.py)."""
import random
import socket


def free_port():
    """A base port P with P..P+3 free on 127.0.0.1: a node's three channels and its metrics."""
    while True:
        p = random.randint(20000, 40000)
        ok = True
        for q in range(p, p + 4):
            with socket.socket() as s:
                try:
                    s.bind(("127.0.0.1", q))
                except OSError:
                    ok = False
        if ok:
            return p
