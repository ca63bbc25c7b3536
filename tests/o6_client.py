"""Read OPC UA nodes with open62541 (``o6``) in a process of its own; JSON in, JSON out.

The free o6 build ends its process ten minutes after it starts; run here, a slow test
session can never lose its pytest worker to that timer. Input (stdin): ``url``,
``cert``, ``key``, ``trust``, ``user``, ``password``, ``policy``, ``nodes``; output
(stdout, last line): ``{"values": {node: value}}`` or ``{"error": "..."}``.
DateTime values are given as seconds since 1970-01-01 UTC.
"""

from __future__ import annotations

import json
import sys

FILETIME_1970 = 116_444_736_000_000_000
"""OPC UA DateTime of 1970-01-01 UTC: 100 ns ticks since 1601-01-01."""


def main() -> None:
    args = json.loads(sys.stdin.read())
    import o6

    client = o6.Client(
        args["url"],
        certificate=args["cert"],
        privateKey=args["key"],
        trustList=[args["trust"]],
        securityMode=3,  # SignAndEncrypt
        securityPolicy=args["policy"],
        applicationUri=args["application_uri"],
        username=args["user"],
        password=args["password"],
        # asyncua announces the user-name token with policy None inside a SignAndEncrypt
        # channel (the channel encrypts the password); open62541 needs this switch for it
        allowNonePolicyPassword=True,
    )
    try:
        client.connect(createDefaultSubscription=False)
    except o6.StatusCodeError as exc:
        print(json.dumps({"error": f"StatusCodeError {exc}"}))
        return
    try:
        values = {}
        for node in args["nodes"]:
            try:
                value = client.read(node)
            except o6.StatusCodeError as exc:
                print(json.dumps({"error": f"{node}: StatusCodeError {exc}"}))
                return
            if isinstance(value, o6.DateTime):
                value = (int(value) - FILETIME_1970) / 1e7
            elif not isinstance(value, bool | str | float) and hasattr(value, "__index__"):
                value = int(value)  # an o6 Int32
            values[node] = value
    finally:
        client.disconnect()
    print(json.dumps({"values": values}))


if __name__ == "__main__":
    main()
