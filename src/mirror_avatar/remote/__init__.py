"""Remote studies: participants at home, reaching the lab server over the internet.

`network` declares an emulated internet (one-way delays with jitter per direction, stalls) from
one spec string; `proxy` puts it between pages and a lab server as a TCP proxy on loopback,
writing the truth of every chunk it carried (`truth`), for browser tests and ``lab pilot``.
"""
