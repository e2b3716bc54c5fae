"""The shortcuts a remote skill call takes, each checked against the long way it replaces.

A host loads the node's generator only when the skill uses it (``LazyRandom``) and keeps one
validated parameters object per node; values that need no tags skip the tagging walk;
attachments of our own are packed without building an Attachment. Each must give exactly what
the long way gives, or the distributed run drifts from the local one.
"""

from __future__ import annotations

import random
from typing import Any

import pytest
from pydantic import BaseModel

from botstage.robots.clock import SimClock
from botstage.robots.remote import values
from botstage.robots.ros2 import attachment
from botstage.skills.base import Outcome, Skill, SkillContext, SkillRun
from botstage.skills.registry import Registry
from botstage.skills.remote import rng
from botstage.skills.remote.host import SkillHost
from botstage.skills.remote.protocol import Call, DirectLink, Step, TickRequest, request_fields, request_of

# every public method of random.Random, with arguments: a new one fails the first test until
# it is listed here (and checked below to be seen when it touches the state)
CALLS: dict[str, tuple[Any, ...]] = {
    "betavariate": (2.0, 3.0),
    "binomialvariate": (10, 0.3),
    "choice": ([1, 2, 3],),
    "choices": ([1, 2, 3], [1, 2, 3]),
    "expovariate": (1.5,),
    "gammavariate": (2.0, 1.0),
    "gauss": (),
    "getrandbits": (70,),
    "getstate": (),
    "lognormvariate": (0.0, 1.0),
    "normalvariate": (),
    "paretovariate": (2.0,),
    "randbytes": (9,),
    "randint": (1, 6),
    "random": (),
    "randrange": (10, 1000, 7),
    "sample": (list(range(20)), 5),
    "seed": (42,),
    "setstate": (random.Random(99).getstate(),),
    "shuffle": (list(range(10)),),
    "triangular": (),
    "uniform": (1.0, 2.0),
    "vonmisesvariate": (0.5, 2.0),
    "weibullvariate": (1.0, 2.0),
}


def public_methods() -> set[str]:
    return {name for name in dir(random.Random) if not name.startswith("_") and callable(getattr(random.Random, name))}


def a_state(with_cached_gauss: bool) -> tuple[Any, ...]:
    source = random.Random("node")
    source.random()
    if with_cached_gauss:
        source.gauss()  # leaves the second Gaussian cached: the next gauss() only takes it
    return source.getstate()


def test_every_method_of_random_is_checked() -> None:
    assert public_methods() <= set(CALLS) | {"VERSION"}


@pytest.mark.parametrize("cached", [False, True], ids=["plain", "gauss_cached"])
@pytest.mark.parametrize("packed", [False, True], ids=["tuple", "bytes"])
@pytest.mark.parametrize("method", sorted(set(CALLS) & public_methods()))  # binomialvariate: Python 3.12 on
def test_lazy_random_draws_what_random_draws_and_notices_any_change(method: str, packed: bool, cached: bool) -> None:
    state = a_state(cached)
    lazy, plain = rng.LazyRandom(rng.pack(state) if packed else state), random.Random()
    plain.setstate(state)
    arguments = CALLS[method]
    mine = [list(a) if isinstance(a, list) else a for a in arguments]  # shuffle works in place
    assert getattr(lazy, method)(*mine) == getattr(plain, method)(*arguments)
    assert mine == [list(a) if isinstance(a, list) else a for a in arguments]
    assert lazy.getstate() == plain.getstate()
    changed = plain.getstate() != state
    assert lazy.used is (changed or method in ("seed", "setstate"))
    assert lazy.random() == plain.random()  # and it goes on as the plain one does


def test_lazy_random_reads_its_state_without_loading_it() -> None:
    state = a_state(True)
    lazy = rng.LazyRandom(rng.pack(state))
    assert lazy.getstate() == state and lazy.initial() == state and not lazy.used
    assert rng.LazyRandom(None).initial() is None
    fresh = rng.LazyRandom(None)
    fresh.random()
    assert fresh.used and fresh.initial() is None


def test_a_malformed_packed_state_is_refused_before_the_call_starts() -> None:
    assert rng.check(rng.pack(a_state(False)))
    with pytest.raises(ValueError, match="a random state is"):
        rng.check(b"\x03" + bytes(10))


# -- the host: the generator comes back only when drawn from; parameters per node -------------


class Knobs(BaseModel):
    gain: float = 1.0
    pair: Any = None


class Draws(Skill):
    """Draws from the node's generator when told to; reports its parameters' identity."""

    name = "draws"
    Params = Knobs

    def run(self, ctx: SkillContext) -> SkillRun:
        if ctx.params.gain > 1:
            ctx.rng.random()
        return Outcome("success")
        yield


def start(host: SkillHost, node: str, params: dict[str, Any], state: tuple[Any, ...] | None) -> Any:
    call = Call("draws", node, {}, params, state)
    request = request_of(request_fields(TickRequest(f"{node}{params}", Step.START, 0.0, 0, 0.1, True, call)))
    assert isinstance(request.call.rng_state, bytes)  # the host reads the packed state only if it is used
    return host.handle(request)


def test_the_host_returns_the_generator_only_when_the_skill_drew() -> None:
    host = SkillHost(Registry([Draws]), {})
    state = a_state(False)
    try:
        assert start(host, "/a", {}, state).rng_state is None
        drawn = start(host, "/a", {"gain": 2.0}, state).rng_state
        local = random.Random()
        local.setstate(state)
        local.random()
        assert drawn == local.getstate()
    finally:
        host.close()


def test_the_host_validates_parameters_once_per_node_and_values() -> None:
    host = SkillHost(Registry([Draws]), {})
    try:
        same = [host.params(Call("draws", "/a", {}, {"gain": 2.0})) for _ in range(2)]
        assert same[0] is same[1] and same[0].gain == 2.0
        assert host.params(Call("draws", "/b", {}, {"gain": 2.0})) is not same[0]  # another node: its own
        assert host.params(Call("draws", "/a", {}, {"gain": 3.0})).gain == 3.0
        as_list = host.params(Call("draws", "/a", {}, {"pair": [1, 2]}))
        as_tuple = host.params(Call("draws", "/a", {}, {"pair": (1, 2)}))
        assert as_list.pair == [1, 2] and as_tuple.pair == (1, 2)  # values that JSON would blur stay apart
        assert host.params(Call("draws", "/a", {}, {"gain": -0.0})).gain.hex() == (-0.0).hex()
        with pytest.raises(ValueError):
            host.params(Call("draws", "/a", {}, {"gain": "loud"}))
    finally:
        host.close()


def test_a_remote_call_of_a_skill_that_never_draws_leaves_the_generator_alone() -> None:
    from botstage.skills.base import SkillLogger
    from botstage.skills.execution import SkillExecution
    from botstage.skills.remote.proxy import remote_of

    host = SkillHost(Registry([Draws]), {})
    try:
        node_rng = random.Random("n")
        before = node_rng.getstate()
        clock = SimClock(10.0)
        ctx = SkillContext(clock, Knobs(), SkillLogger("/n"), {}, None, rng=node_rng, node="/n")  # type: ignore[arg-type]
        assert SkillExecution(remote_of(Draws, DirectLink(host))(), ctx).start({}) == Outcome("success")
        assert node_rng.getstate() == before
    finally:
        host.close()


# -- values and attachments -----------------------------------------------------------------


@pytest.mark.parametrize(
    "value",
    [
        {"a": 1, "b": [1.5, None, True, "x"], "c": {"d": []}},
        {"$x": 1},
        {"a": (1, 2)},
        [float("inf")],
        {1: 2},
        'has "$tuple" inside',
        {"s": '"$tuple'},
        [True, 1, 1.0],
    ],
)
def test_the_plain_json_shortcuts_give_what_the_tagging_walk_gives(value: Any) -> None:
    import json

    text = values.dumps(value)
    assert text == json.dumps(values._pack(value, "v"), separators=(",", ":"), ensure_ascii=False)
    back = values.loads(text)
    assert back == values._unpack(json.loads(text)) and back == value
    assert values.loads('{"\\u0024tuple":[1]}') == (1,)  # an escaped tag is still a tag


def test_packed_attachments_are_the_encoded_ones() -> None:
    gid = bytes(range(16))
    sent = attachment.Attachment(7, -3, gid)
    assert attachment.pack(7, -3, gid) == attachment.encode(sent)
    assert attachment.unpack(attachment.encode(sent)) == (7, -3, gid)
    assert attachment.decode(attachment.encode(sent)) == sent
    with pytest.raises(attachment.AttachmentError):
        attachment.unpack(bytes(5))
