"""One run of a skill, driven tick by tick, that never lets an exception escape.

Trees, machine states and remote peers all run skills through this class, so inputs are
validated, outcomes and outputs are checked against the contract, futures are waited on and
cancellation runs the skill's ``finally`` in exactly one place.
"""

from __future__ import annotations

from collections.abc import Generator, Mapping
from concurrent.futures import Future
from types import MappingProxyType
from typing import Any

from botstage.skills.base import FAILURE, MISSING, Outcome, Skill, SkillContext, check_type


def describe_exception(exc: BaseException) -> str:
    text = str(exc)
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


class SkillExecution:
    """Start, step and cancel one skill; every way it ends becomes an ``Outcome``."""

    __slots__ = ("_gen", "_waiting", "ctx", "skill")

    def __init__(self, skill: Skill, ctx: SkillContext) -> None:
        self.skill = skill
        self.ctx = ctx
        self._gen: Generator[Any, Any, Any] | None = None
        self._waiting: Future[Any] | None = None

    @property
    def running(self) -> bool:
        return self._gen is not None

    def start(self, inputs: Mapping[str, Any]) -> Outcome | None:
        """Begin a run and take its first step. Returns the outcome if it ended in that step."""
        if self._gen is not None:
            self.cancel()
        skill = self.skill
        try:
            args = self._check_inputs(inputs) if (inputs or skill.inputs) else {}
        except (TypeError, ValueError) as exc:
            return Outcome(FAILURE, str(exc))
        try:
            if not skill.is_generator:
                return self._finish(skill.run(self.ctx, **args))
            self._gen = skill.run(self.ctx, **args)
        except Exception as exc:  # a skill never crashes the caller
            return self._crashed(exc)
        return self._advance(None, None)

    def step(self) -> Outcome | None:
        """Advance one tick; ``None`` while the skill is still running."""
        waiting = self._waiting
        if waiting is not None:
            if not waiting.done():
                return None
            self._waiting = None
            exc = waiting.exception()
            if exc is not None:
                return self._advance(None, exc)
            return self._advance(waiting.result(), None)
        return self._advance(None, None)

    def cancel(self) -> str | None:
        """Stop the run: close the generator so its ``finally`` runs now.

        Returns ``None`` if cleanup went well, or the reason it did not.
        """
        gen, self._gen = self._gen, None
        waiting, self._waiting = self._waiting, None
        if waiting is not None:
            waiting.cancel()
        if gen is None:
            return None
        try:
            gen.close()
        except Exception as exc:
            return f"cleanup raised {describe_exception(exc)}"
        return None

    # -- internals -------------------------------------------------------------------------

    def _advance(self, value: Any, exc: BaseException | None) -> Outcome | None:
        gen = self._gen
        assert gen is not None
        try:
            yielded = gen.send(value) if exc is None else gen.throw(exc)
        except StopIteration as stop:
            self._gen = None
            return self._finish(stop.value)  # outside the generator: checks never raise into it
        except Exception as error:
            self._gen = None
            return self._crashed(error)
        if isinstance(yielded, Future):
            self._waiting = yielded
        return None

    def _crashed(self, exc: Exception) -> Outcome:
        self.ctx.logger.error(f"skill {self.skill.name!r} raised {describe_exception(exc)}")
        return Outcome(FAILURE, f"raised {describe_exception(exc)}")

    def _finish(self, result: Any) -> Outcome:
        skill = self.skill
        if type(result) is str:
            result = Outcome(result)
        elif not isinstance(result, Outcome):
            return Outcome(FAILURE, f"run() returned {type(result).__name__} instead of an Outcome")
        if not isinstance(result.name, str) or not isinstance(result.reason, str):
            return Outcome(FAILURE, "run() returned an Outcome whose name or reason is not a string")
        outputs_type = type(result.outputs)
        # exact types first: an ABC isinstance check costs more than the rest of a skill run
        if (
            outputs_type is not dict
            and outputs_type is not MappingProxyType
            and not isinstance(result.outputs, Mapping)
        ):
            return Outcome(FAILURE, f"run() returned outputs as {type(result.outputs).__name__}, not a mapping")
        if result.name not in skill.all_outcomes:
            declared = ", ".join(sorted(skill.all_outcomes))
            return Outcome(FAILURE, f"returned undeclared outcome {result.name!r} (declared: {declared})")
        if result.outputs:
            declared_out = skill.outputs
            for port, value in result.outputs.items():
                spec = declared_out.get(port)
                if spec is None:
                    return Outcome(FAILURE, f"returned undeclared output {port!r}")
                try:
                    check_type(spec.type, value)
                except TypeError as err:
                    return Outcome(FAILURE, f"output {port!r}: {err}")
        return result

    def _check_inputs(self, given: Mapping[str, Any]) -> dict[str, Any]:
        declared = self.skill.inputs
        unknown = set(given) - set(declared)
        if unknown:
            raise ValueError(f"unknown input {sorted(unknown)[0]!r} for skill {self.skill.name!r}")
        args: dict[str, Any] = {}
        for port_name, port in declared.items():
            value = given.get(port_name, port.default)
            if value is MISSING:
                raise ValueError(f"input {port_name!r} is required but was not given")
            try:
                args[port_name] = check_type(port.type, value)
            except TypeError as err:
                raise TypeError(f"input {port_name!r}: {err}") from None
        return args
