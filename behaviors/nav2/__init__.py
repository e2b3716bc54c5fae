"""Nav2's behaviour-tree controls, decorators and goal conditions as botstage node kinds (a plug-in set)."""
