"""The chatbot behind the `converse` skill and `botstage chat`, and the voice behind `speak`.

Maya, the PeopleBot entertainer's character, talks through an AIML kernel (python-aiml, as in
chapter 3 of *ROS Robotics Projects*): the bundled A.L.I.C.E. set plus her own categories in
``aiml/``. What a visitor says is either a robot command, which goes to the mission as an
outcome, or conversation, which goes to the kernel.

- ``learn``: AIML files to categories, every broken file a located problem (the rest still loads)
- ``brain``: the learned pattern tree in a flat form that loads in milliseconds
- ``cache``: the brain file cache, keyed by the AIML files' contents
- ``kernel``: python-aiml's kernel made safe for a robot (no shell, seeded, mission calendar)
- ``persona``: Maya's AIML files and bot predicates
- ``routing``: which utterances are robot commands
- ``chatbot``: one run's Maya: the shared brain, a session per visitor
- ``tts``: text to speech with espeak-ng
"""
