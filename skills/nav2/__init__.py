"""Nav2's behaviour-tree actions and conditions as botstage skills, on botstage's navigation stack.

Nav2's BT nodes are clients of ROS servers (planner, controller, behaviours, costmaps); here each
one calls the robot's ``NavStack`` directly, so Nav2's unmodified XML drives a simulated or real
botstage robot. Ports are named, typed and defaulted as ``nav2_tree_nodes.xml`` declares them;
the ones that only address ROS (``server_name``, ``server_timeout``, ``*_id`` of plug-ins,
frames, topics) are accepted and ignored (see ``common.ignored``). Registered as a plug-in set
through the ``botstage.skills`` entry points in pyproject.toml.
"""
