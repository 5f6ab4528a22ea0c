"""The physics core: what a tick needs, the scene description and the bot API (bot.py) that a scene names."""
