"""ROS 2 over Zenoh: rmw_zenoh's wire format (keys, liveliness, attachments, CDR) and ROS 2 messages."""
