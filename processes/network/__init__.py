"""The network layer, in rooms over the wire they share.

wire/ (the bottom): every message's layout, its checks, the codec, the net's knots on the wire
and the generator of the protocol document. Above it, independent of each other (import
contracts in pyproject.toml): server/ (the gateway's sessions and sockets, seats, feed, relay,
snapshot pacing) and client/ (a client's session, its play or watch loop, prediction,
interpolation, the bot and the keyboard). web/ (the bridge to browsers, the browser's player,
the replay page, static/) is a client like any other: it stands on client/ and never on server/.
"""
