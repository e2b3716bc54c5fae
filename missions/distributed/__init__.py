"""One mission across processes: deployments started together, processes by their roles.

``supervisor`` starts a deployment's processes on this machine and stops them together
(``botstage up``); each process runs its role from the deployment file (``botstage serve``):
the robot's devices, skills for the mission, the gallery, the mission itself.
"""
