"""The live monitor and debugger in the browser: a run's trees and machines, blackboard, timeline
and logs as they change; pause, step, breakpoints, forced outcomes, e-stop; finished runs
scrubbed tick by tick; and the robot's tablet page (``/display``)."""
