"""BehaviorTree.CPP v4: its built-in node set (``nodes``) and XML import (``xml_reader``, ``to_spec``)."""
