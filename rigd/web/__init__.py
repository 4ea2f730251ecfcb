"""The browser console: ``rigd web``, a client of the daemon's control socket.

It runs in its own process; the loop's real-time process is never touched by a browser.
"""
