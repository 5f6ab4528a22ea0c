"""The network layer: wire protocol, gateway sockets, clients, prediction, interpolation, keyboard play."""
