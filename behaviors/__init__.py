"""How skills are composed: the execution engine (blackboard, trees, machines, trace)."""
