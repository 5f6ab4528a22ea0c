"""The runtime layer: shared memory, locks, mailboxes, hand-off batons and worker control (no sockets)."""
