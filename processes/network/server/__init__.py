"""The server side of the network: the gateway's sessions and sockets (gateway), the seat table
that outlives a gateway (seats), the spectator feed (feed), its relay (relay) and when a snapshot
is due (pacing). It knows the wire, never a client, and never reads shared memory: the gateway
worker (processes.workers.gateway) feeds it."""
