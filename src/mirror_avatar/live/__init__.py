"""Live mirror game in the browser.

`protocol` parses and validates the messages a browser sends, `session` runs one trial (advancing
an engine `Player` every control period and appending every sample to disk as it goes), and
`server` is the ASGI application that serves the page and the WebSocket. The command
``mirror-avatar play`` starts it (`mirror_avatar.cli.play`).
"""
