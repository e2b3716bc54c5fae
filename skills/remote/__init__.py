"""Skills run by another process: the same contract, driven tick by tick over a link.

A mission that runs a skill remotely holds a *proxy* (``proxy.remote_of``) with the real skill's
ports, parameters and outcomes, so trees, machines, checks and the trace cannot tell it from the
local one. Each tick the proxy sends one ``TickRequest`` (the first carries the call: inputs,
parameters, node, the node's random state) with the blackboard keys the node may read, and gets one ``TickReply``:
still running, or the outcome with its reason and outputs, plus the node's log lines and
blackboard writes in the order they happened, which the proxy replays where a local skill would
have made them. The other process holds a ``host.SkillHost``: it runs the real skill through
``SkillExecution`` on one thread, on a clock set by the requests, so the skill sees the mission's
time. Values travel as tagged JSON (``botstage.robots.remote.values``): tuples stay tuples, so a distributed run is
byte-identical to a local one.

The link is a protocol (``proxy.SkillLink``); ``robots/ros2``'s services carry it between
processes. A link that loses its peer fails the running node with the reason
(``remote 'kinect_pc' lost``).
"""
