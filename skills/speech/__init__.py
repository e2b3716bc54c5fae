"""Speech algorithms behind the listen skill: WAV files, voice activity detection, the recogniser.

Nothing here knows about skills or the engine: the recogniser is plain blocking code that the
skill runs through ``ctx.submit``, and that the command line and the benchmark call directly.
"""
