"""The router: runs each configured route's translator between transports.

`router` (the `Router`: the transports a config names, a route runner per route, their stats),
`runner` (one route: lanes, lazy routes, its worker), `flow` (how a message waits for a worker or
is translated on the transport's thread), `stats` and `status` (what the router reports),
`echoes` (the way back's own messages, recognised) and `workers` (routes in worker processes).
"""
