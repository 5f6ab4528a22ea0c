"""The client side of the network: a session with a gateway and its feed (client), the play or
watch loop (session), the player's prediction (prediction), the spectator's interpolation
(interpolation) and the two pilots of a bat, the bot (bot) and the keyboard (keyboard). It
knows the wire, never the server's code."""
