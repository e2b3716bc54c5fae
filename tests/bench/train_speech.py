"""Train the command classifier on the speech embedding: `python -m tests.bench train-speech`.

Everything it hears is made here with espeak-ng, and none of it is the benchmark's
(tests/bench/bench_speech.py) or the tuning set's:

- **voices**: espeak-ng's English voices (``BASES``) with its variants (``VARIANTS``), every pair
  except the benchmark's ``VOICES`` and the tuning ``TUNE_VOICES`` (``en`` is ``en-gb``, so
  ``en+klatt`` excludes ``en-gb+klatt``), and no voice without a variant (the benchmark has two);
  ``TRAIN_VOICES`` of them are drawn with a fixed seed;
- **speeds** ``TRAIN_SPEEDS`` and **pitches** ``TRAIN_PITCHES``: none of the benchmark's (130, 170,
  210 words a minute; pitch 35, 65) nor the tuning set's (150, 190; 50);
- **phrases**: the five commands, and as ``other`` ``NEGATIVES``: everyday phrases and near-miss
  words ("photography", "cattle", "chowder", "what's going on"), none of the benchmark's
  ``PHRASES`` nor the tuning ``TUNE_PHRASES``.

Each clip is heard ``COPIES`` times: once over the simulator's room noise, and augmented: white,
pink or brown noise at 0-25 dB SNR, a synthetic room's reverberation (exponential decay, RT60
0.15-0.6 s) on a third, speed perturbation (resampling by 0.88-1.12) on a third, gain from -18 to
+6 dB or, on one in six, a microphone overdriven by 6-14 dB and hard clipped. Every copy goes
through the benchmark's own path (half a second of noise either side, the voice activity
detector), and its longest utterance is embedded: the classifier is trained on what it will be
given.

The classifier (skills/speech/embedding.py) is one hidden layer of ``HIDDEN`` tanh units and a
softmax, cross-entropy with an L2 penalty, classes weighted to equal total weight, fitted with
SciPy's L-BFGS from a seeded start. Each command's threshold is then chosen on the tuning voices,
speeds, pitches and phrases (bench_speech.py's ``TUNE_*``), heard clean and in white and pink
noise at 20 and 10 dB SNR exactly as the benchmark hears its own: the most commands found with
false accepts at or under ``TUNE_FALSE_ACCEPTS`` in every tuning condition (``choose_thresholds``).
The weights, the thresholds and how they were made (``meta``) go to
skills/speech/models/commands.npz; CI only loads them.

How it got here (tuning set only; commands / false accepts in %, clean, white 20, white 10,
pink 20, pink 10 dB; the benchmark was not run on any of these):

1. 36 negatives a voice from the first half of ``NEGATIVES``, a softmax regression: near
   every command found at a threshold of 0.5-0.9 (94-100 %), but 9-24 % false accepts, nearly all
   near-homophones: "yet" taken for YES (94 of 100), "console", "counsel", "cancer" for CANCEL,
   "photon" and "photo booth" for PHOTO, "sure" for CIAO, "what's that" for WHATSUP. With the
   first rule (false accepts <= 2 % everywhere) the threshold went to 0.99, the top of the
   sweep: 83 / 89 / 70 / 86 / 66 at 2.9 / 2.9 / 4.0 / 2.1 / 2.3.
2. The second half of ``NEGATIVES`` added (the same kinds of word, none of the tuning set's:
   "jet", "yen", "consul", "pencil", "proton", "photo album", "shore", "what's wrong"), 64 a
   voice: at 0.9, 96 / 98 / 97 / 99 / 94 at 7.1 / 10.2 / 9.8 / 5.8 / 7.3; "yet" is still most of
   what is left (27 of 100 at 0.99).
3. A hidden layer of 64 units: at 0.9, 96 / 99 / 97 / 100 / 96 at 4.4 / 5.4 / 7.1 / 5.4 / 6.7;
   at 0.95, 93 / 98 / 92 / 98 / 90 at 3.5 / 3.3 / 5.8 / 3.8 / 5.2.
4. The rule: 2 % drove the threshold to 0.99, where commands in 10 dB noise fall to 56-67 %;
   it is now 4 % (a point under the benchmark's 5 % target, on a tuning set chosen harder than
   the benchmark's phrases). Changed after seeing the tuning curve, never the benchmark.

Second session (the benchmark had been run once, at step 4: 93 / 91 / 81 / 88 / 84 at
0.0-0.1 %; nothing below was measured on it until the weights were final):

5. Phrases with a command word in them ("yes sir", "photo album" in training; "yes please",
   "photo booth" in tuning) are neither a command nor something else: a robot that asks for YES
   and hears "yes please" should take YES. Dropped from both (``has_command_word`` now refuses
   them); the tuning set says "bless you" and "motor boat" instead. Pooled, 48 voices, one
   threshold: 89 / 93 / 84 / 95 / 78 at 1.2 / 2.7 / 4.0 / 1.9 / 2.9 (0.98); "yet" is 45 of the
   false accepts, "counsel" and "console" 13.
6. The sequence beside the pooled vectors (five vectors evenly along the utterance, or around
   its middle; 769 numbers): at 0.98, 90 / 95 / 84 / 95 / 88 at 0.8 / 2.1 / 4.6 / 0.8 / 2.7 and
   90 / 94 / 83 / 92 / 79 at 1.2 / 2.3 / 4.0 / 1.0 / 3.1, against pooled 90 / 93 / 81 / 93 / 78
   at 0.6 / 2.1 / 3.3 / 1.0 / 3.1 (before step 5): not kept, a fit takes twice as long for a
   curve that is hardly better. 128 hidden units: worse (87 / 92 / 72 / 89 / 71 at 0.98).
7. 144 training voices instead of 48 (52,700 utterances): at 0.9, 97 / 100 / 98 / 100 / 99 at
   4.6 / 5.6 / 7.1 / 5.4 / 7.1, against 96 / 100 / 96 / 100 / 95 at 4.2 / 5.0 / 6.9 / 5.2 / 6.2.
8. A threshold per command (``choose_thresholds``): one confusable word held every command
   back. On step 7's model, 95 / 100 / 95 / 97 / 89 at 1.2 / 2.5 / 4.0 / 2.9 / 3.3 against one
   threshold's 90 / 93 / 87 / 95 / 82 at 0.4 / 2.1 / 4.4 / 1.5 / 2.9 (0.98, over the budget).
9. Clipping in the augmentation (an overdriven microphone on one copy in six).

Third session (the benchmark had been run once more, on step 9's weights: 96.7 / 96.7 / 92.7 /
94.7 / 89.3 at 0.0 %, CANCEL held at the grid's top, 0.99):

10. Phoneme near misses as negatives, openWakeWord's adversarial phrases: each command spelt in
    espeak-ng's phonemes with the stressed vowel, then also the consonant before or after it,
    changed to each other one (``[[k'Ens@L]]``; none spelling a benchmark or tuning phrase), 24
    a voice. On the ten tuning voices: 91 / 93 / 92 / 95 / 89 (vowel and onset), 95 / 96 / 93 /
    98 / 94 (and coda), against 96 / 98 / 94 / 97 / 93 for step 9's: not better, and twenty
    commands a cell could not tell them apart.
11. So the tuning set grew: 30 more voices (``tuning_voices``, drawn from the pairs neither
    training nor the benchmark uses), 80 commands a command and condition. There step 9's
    network finds 465 (summed over the conditions), step 10's 452 and 443: near misses dropped.
    Step 9's thresholds break the rule there (4.5 % and 4.3 % at 10 dB); chosen again on the 40
    voices (``python -m tests.bench train-speech --thresholds-only``): PHOTO 0.93, YES 0.97, WHATSUP 0.95,
    CANCEL 0.96, CIAO 0.92, finding 95.8 / 95.0 / 89.5 / 95.2 / 89.5 at 1.2-4.0 %, which is also
    close to what the benchmark had measured on step 9: the larger set predicts it. The
    benchmark, run once on these: 98.7 / 98.0 / 95.3 / 96.3 / 95.0 at 0.0-0.1 %.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import os
import pickle
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import minimize
from scipy.signal import fftconvolve, resample_poly

from botstage.skills.speech.embedding import CLASSES, Classifier, SpeechEmbedding, pooled, weights_path
from botstage.skills.speech.recognizer import COMMANDS
from botstage.skills.speech.vad import find_utterances
from tests.bench.bench_speech import (
    PAD,
    PHRASES,
    SAY,
    TUNE_PHRASES,
    TUNE_PITCHES,
    TUNE_SPEEDS,
    TUNE_VOICES,
    VOICES,
    mix,
    noise,
    speech_power,
    synthesise,
)

BASES = ("en-us", "en-gb", "en-gb-scotland", "en-gb-x-gbclan", "en-gb-x-rp", "en-gb-x-gbcwmd", "en-029", "en-us-nyc")
VARIANTS = (
    *(f"m{i}" for i in range(1, 9)),
    *(f"f{i}" for i in range(1, 6)),
    "klatt", "klatt2", "klatt3", "klatt4", "klatt5", "klatt6",
    "adam", "Alex", "Andy", "aunty", "boris", "david", "ed", "edward", "john", "linda", "max",
    "michel", "paul", "quincy", "rob", "robert", "steph", "travis", "victor", "zac", "norbert",
    "shelby", "Annie", "belinda", "grandpa", "iven", "Mike", "Lee", "Jacky",
)  # fmt: skip
TRAIN_VOICES = 144
TRAIN_SPEEDS = (115, 140, 160, 180, 200, 225)
TRAIN_PITCHES = (25, 42, 58, 75)
COPIES = 4  # the room-noise copy and three augmented ones
AUGMENTATION = 2  # augment()'s version, part of the cache key: 2 added clipping
NEGATIVES_PER_VOICE = 64
MORE_TUNE_VOICES = 30  # drawn beside bench_speech's ten TUNE_VOICES (see tuning_voices)
TUNE_FALSE_ACCEPTS = 4.0  # % of the tuning phrases, in every tuning condition (see the docstring)
L2 = 1e-3
HIDDEN = 64  # units in the hidden layer; 0: a softmax regression
SEED = 20

NEGATIVES = (
    # near misses: sounds shared with a command
    "photography", "photographer", "photocopy", "potato", "photos of cats", "motto", "lotto",
    "ghetto", "auto", "focus", "fortune", "so so", "foe", "toe", "follow", "pho soup",
    "yeah", "yep", "yeast", "guess", "less", "mess", "chess", "dress", "yesterday's news",
    "yell", "jess", "address", "success",
    "what's going on", "what's this", "what's happening", "watch out", "what a day", "water",
    "wake up", "hold up", "what's for dinner", "what sort", "hiccup", "catch up", "what's the time",
    "candle", "council", "channel", "tunnel", "kennel", "cattle", "camel", "tassel",
    "cancun", "can sell", "cancellation", "parcel", "chancel", "can", "scandal",
    "chow", "cow", "now", "meow", "chowder", "chair", "child", "chat", "child's play", "chip", "ow",
    "tao", "bow wow", "ciabatta", "chowhound", "how now", "allow", "towel",
    # second round, after the tuning set showed which kinds of words were taken for commands
    # ("yet", "console", "sure", "photon", "photo booth", "what's new": none of them is here)
    "jet", "yen", "yeti", "get", "let", "net", "set", "bet", "yam", "yak", "yum", "yolk", "young",
    "consul", "concert", "consult", "pencil", "stencil", "tinsel", "cancan", "canteen", "kansas",
    "can't sell", "chancellor", "counter", "cancelled flights",
    "proton", "futon", "motor", "total", "foetus",
    "photographs", "potion", "float", "phone", "fold", "foam",
    "shore", "shoe", "sugar", "chore", "jaw", "show", "shower", "shout", "chart", "chew",
    "what's it", "what's wrong", "what's next", "what's on", "whatever", "what's the matter",
    "what's his name", "what's cooking", "watts", "what's that noise", "wasp", "what's yours",
    "whoa", "now then", "how so", "out", "vow", "bow", "wow that's cool", "cow bell",
    # third round: a phrase with a command word in it ("yes sir", "photo album") is no longer a
    # negative (see _check_disjoint); near misses without the word instead
    "yikes", "vest", "quest", "soda", "fodder", "kettle", "cavil", "chai", "jowl", "what's left",
    "watch it",
    # everyday phrases
    "good afternoon", "good evening", "good night", "see you later", "have a nice day",
    "where are the toilets", "how much is it", "can you help me", "I am lost", "who are you",
    "what are you doing", "this is great", "I don't know", "let's go", "come here", "stop it",
    "turn left", "turn right", "go straight", "over there", "not now", "thank you", "you're welcome",
    "I'm sorry", "pardon", "really", "of course", "absolutely not", "never mind", "excellent",
    "how old are you", "where do you live", "do you like music", "tell me a joke", "sing a song",
    "my name is anna", "nice to meet you", "the weather is nice today", "it is raining",
    "it's very cold", "I'm hungry", "where is the cafe", "is it far", "how long does it take",
    "one two three", "four five six", "seven eight nine", "ten", "twenty", "a hundred",
    "red green blue", "monday", "tuesday", "saturday", "january", "september", "birthday party",
    "the museum closes at six", "look at that", "amazing", "funny robot", "are you a robot",
    "can you dance", "I want a drink", "coffee please", "tea with milk", "the bus is late",
    "listen to me", "speak up", "be quiet", "hurry up", "slow down", "wait for me",
    "my friends are here", "the children are playing", "how does it work", "who made you",
    "is this free", "where is my phone", "what is this place", "I love it", "not bad",
    "pretty good", "all right", "alright then", "hmm", "uh huh", "oh no", "oops", "hey", "hi",
    "bye bye", "cheers", "later", "thanks a lot", "see you soon", "good luck", "congratulations",
)  # fmt: skip


def _normal(voice: str) -> str:
    base, _, variant = voice.partition("+")
    return f"{'en-gb' if base == 'en' else base}+{variant}"


def training_voices(n: int = TRAIN_VOICES) -> list[str]:
    """``n`` voice+variant pairs, none of them the benchmark's or the tuning set's."""
    taken = {_normal(v) for v in (*VOICES, *TUNE_VOICES)}
    pairs = [f"{b}+{v}" for b, v in itertools.product(BASES, VARIANTS) if _normal(f"{b}+{v}") not in taken]
    rng = np.random.default_rng(SEED)
    return [pairs[i] for i in sorted(rng.choice(len(pairs), size=n, replace=False))]


def tuning_voices(n: int = MORE_TUNE_VOICES) -> list[str]:
    """The tuning voices: bench_speech's ``TUNE_VOICES`` and ``n`` pairs drawn from those that
    neither training (``training_voices``) nor the benchmark uses. Ten voices gave 20 commands a
    command and condition, too few to tell two models' curves apart."""
    taken = {_normal(v) for v in (*VOICES, *TUNE_VOICES, *training_voices())}
    pairs = [f"{b}+{v}" for b, v in itertools.product(BASES, VARIANTS) if _normal(f"{b}+{v}") not in taken]
    rng = np.random.default_rng(SEED + 3)
    return [*TUNE_VOICES, *(pairs[i] for i in sorted(rng.choice(len(pairs), size=n, replace=False)))]


def has_command_word(phrase: str) -> bool:
    """True when ``phrase`` says a command as whole words ("yes please", "photo album"): to the
    robot that is the command said with more around it, so it is neither trained as ``other``
    nor counted as a false accept."""
    words = f" {' '.join(phrase.lower().replace('-', ' ').split())} "
    return any(f" {text} " in words for text in SAY.values())


def _check_disjoint() -> None:
    said = {p.lower() for p in (*PHRASES, *TUNE_PHRASES)}
    overlap = [p for p in NEGATIVES if p.lower() in said]
    if overlap:
        raise ValueError(f"training phrases the benchmark or the tuning set uses: {overlap}")
    with_command = [p for p in (*NEGATIVES, *TUNE_PHRASES) if has_command_word(p)]
    if with_command:
        raise ValueError(f"negatives with a command word in them (neither command nor other): {with_command}")
    heard = {_normal(v) for v in training_voices()} & {_normal(v) for v in (*VOICES, *tuning_voices())}
    if heard:
        raise ValueError(f"training voices the benchmark or the tuning set uses: {sorted(heard)}")
    if set(TRAIN_SPEEDS) & {130, 170, 210, *TUNE_SPEEDS} or set(TRAIN_PITCHES) & {35, 65, *TUNE_PITCHES}:
        raise ValueError("a training speed or pitch is the benchmark's or the tuning set's")


def reverberate(x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A synthetic room: the direct sound plus exponentially decaying noise (RT60 0.15-0.6 s)."""
    rt60 = rng.uniform(0.15, 0.6)
    n = int(rt60 * 16000)
    t = np.arange(n) / 16000
    ir = rng.normal(0, 1, n) * np.exp(-6.9 * t / rt60)
    ir[: int(0.002 * 16000)] = 0.0
    ir *= rng.uniform(0.2, 0.6) / np.sqrt(np.sum(ir**2))
    ir[0] = 1.0
    wet = fftconvolve(x, ir)[: x.size + n // 2]
    return wet * np.sqrt(np.mean(x**2) / max(np.mean(wet**2), 1e-9))


def augment(samples: np.ndarray, copy: int, seed: int) -> np.ndarray:
    """Copy 0: the benchmark's clean condition (room noise). Others: see the module docstring."""
    if copy == 0:
        return mix(samples, "clean", None, seed)
    rng = np.random.default_rng(seed)
    x = samples.astype(float)
    if rng.random() < 1 / 3:
        factor = rng.uniform(0.88, 1.12)
        up = 100
        x = resample_poly(x, up, round(up * factor))
    if rng.random() < 1 / 3:
        x = reverberate(x, rng)
    if rng.random() < 1 / 6:  # an overdriven microphone: 6-14 dB too loud, hard clipped
        x = np.clip(x * 10 ** (rng.uniform(6, 14) / 20), -32768, 32767)
    else:
        x *= 10 ** (rng.uniform(-18, 6) / 20)
    kind = rng.choice(["white", "pink", "brown"])
    snr = rng.uniform(0, 25)
    size = x.size + 2 * PAD
    if kind == "brown":
        n = np.cumsum(rng.normal(0, 1, size))
        n -= np.convolve(n, np.ones(801) / 801, mode="same")  # keep it from wandering off
        n /= np.sqrt(np.mean(n**2))
    else:
        n = noise(str(kind), size, rng)
    clipped = np.clip(np.round(x), -32768, 32767)
    background = n * np.sqrt(speech_power(clipped.astype(np.int16)) / 10 ** (snr / 10))
    background[PAD : PAD + x.size] += x
    return np.clip(np.round(background), -32768, 32767).astype(np.int16)


def longest_utterance(audio: np.ndarray) -> np.ndarray | None:
    found = find_utterances(audio)
    return max(found, key=lambda u: u.samples.size).samples if found else None


_EMBEDDING: SpeechEmbedding | None = None


Heard = tuple[np.ndarray, float]  # an utterance's embedding vectors (float16) and its duration in seconds


def _heard(embedding: SpeechEmbedding, utterance: np.ndarray) -> Heard:
    return embedding.frames(utterance).astype(np.float16), utterance.size / 16000


def _features(job: tuple[str, str, int, int, int]) -> list[tuple[int, Heard]]:
    """One clip synthesised, heard COPIES times: each copy's longest utterance embedded."""
    global _EMBEDDING
    if _EMBEDDING is None:
        _EMBEDDING = SpeechEmbedding()
    text, voice, speed, pitch, seed = job
    samples = synthesise(text, voice, speed, pitch)
    out = []
    for copy in range(COPIES):
        utterance = longest_utterance(augment(samples, copy, seed * 10 + copy))
        if utterance is not None:
            out.append((copy, _heard(_EMBEDDING, utterance)))
    return out


def jobs(voices: list[str]) -> list[tuple[str, int, tuple[str, str, int, int, int]]]:
    """(label, seed, job) for every training clip: each command at every training speed for
    every voice (pitch drawn), and NEGATIVES_PER_VOICE phrases a voice (speed and pitch drawn)."""
    rng = np.random.default_rng(SEED + 1)
    made = []
    seed = 1_000_000  # far from the benchmark's seeds (0..n) and the tuning run's
    for voice in voices:
        for command, text in SAY.items():
            for speed in TRAIN_SPEEDS:
                seed += 1
                made.append((command, seed, (text, voice, speed, int(rng.choice(TRAIN_PITCHES)), seed)))
        for i in rng.choice(len(NEGATIVES), size=NEGATIVES_PER_VOICE, replace=False):
            seed += 1
            job = (NEGATIVES[i], voice, int(rng.choice(TRAIN_SPEEDS)), int(rng.choice(TRAIN_PITCHES)), seed)
            made.append(("OTHER", seed, job))
    return made


def dataset(voices: list[str], workers: int, cache: Path | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Features, labels (index into CLASSES) and voice index of every usable copy. With ``cache``,
    each clip's embedded utterances are kept there (keyed by text, voice, speed, pitch, seed,
    COPIES and AUGMENTATION), so a run with more phrases or voices computes only the new clips."""
    todo = jobs(voices)
    store: dict[str, list[tuple[int, Heard]]] = {}
    path = cache / "train-frames.pkl" if cache is not None else None
    if path is not None and path.exists():
        store = pickle.loads(path.read_bytes())
    keys = [json.dumps([job, COPIES, AUGMENTATION]) for _, _, job in todo]
    missing = [(k, job) for k, (_, _, job) in zip(keys, todo, strict=True) if k not in store]
    start = time.perf_counter()
    with ProcessPoolExecutor(workers) as pool:
        for n, ((key, _), got) in enumerate(
            zip(missing, pool.map(_features, [job for _, job in missing], chunksize=8), strict=True)
        ):
            store[key] = got
            if n % 500 == 0:
                print(f"  {n}/{len(missing)} new clips, {time.perf_counter() - start:.0f} s", flush=True)
    if path is not None and missing:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(pickle.dumps(store))
    xs, ys, vs = [], [], []
    for key, (label, _, job) in zip(keys, todo, strict=True):
        for _, (frames, seconds) in store[key]:
            xs.append(pooled(frames.astype(np.float32), seconds))
            ys.append(CLASSES.index(label))
            vs.append(voices.index(job[1]))
    return np.array(xs), np.array(ys), np.array(vs)


def fit(
    x: np.ndarray, y: np.ndarray, hidden: int = HIDDEN, l2: float = L2, seed: int = SEED
) -> tuple[np.ndarray, np.ndarray, tuple[tuple[np.ndarray, np.ndarray], ...]]:
    """Standardisation and the layers (see embedding.Classifier): a softmax regression when
    ``hidden`` is 0, else one tanh layer of ``hidden`` units before it. Cross-entropy with the
    classes weighted to equal total weight, an L2 penalty on the weights, L-BFGS from a seeded
    start (so the same data gives the same weights)."""
    mean, scale = x.mean(0), x.std(0) + 1e-6
    z = (x - mean) / scale
    k, d = len(CLASSES), z.shape[1]
    counts = np.bincount(y, minlength=k).astype(float)
    w_sample = (len(y) / (k * np.maximum(counts, 1)))[y]
    w_sample /= w_sample.sum()
    onehot = np.eye(k)[y]
    shapes = [(d, hidden), (hidden,), (hidden, k), (k,)] if hidden else [(d, k), (k,)]
    sizes = [int(np.prod(sh)) for sh in shapes]

    def unpack(theta: np.ndarray) -> list[np.ndarray]:
        out, at = [], 0
        for shape, size in zip(shapes, sizes, strict=True):
            out.append(theta[at : at + size].reshape(shape))
            at += size
        return out

    def loss(theta: np.ndarray) -> tuple[float, np.ndarray]:
        params = unpack(theta)
        if hidden:
            w1, b1, w2, b2 = params
            h = np.tanh(z @ w1 + b1)
        else:
            w2, b2 = params
            h = z
        logits = h @ w2 + b2
        logits -= logits.max(1, keepdims=True)
        logp = logits - np.log(np.exp(logits).sum(1, keepdims=True))
        value = -(w_sample * (onehot * logp).sum(1)).sum() + l2 * (np.sum(w2**2) + (np.sum(w1**2) if hidden else 0))
        g = (np.exp(logp) - onehot) * w_sample[:, None]
        grads = [h.T @ g + 2 * l2 * w2, g.sum(0)]
        if hidden:
            gh = (g @ w2.T) * (1 - h**2)
            grads = [z.T @ gh + 2 * l2 * w1, gh.sum(0), *grads]
        return float(value), np.concatenate([gr.ravel() for gr in grads])

    rng = np.random.default_rng(seed)
    start = np.concatenate([rng.normal(0, 1 / np.sqrt(shape[0]), size) if len(shape) == 2 else np.zeros(size)
                            for shape, size in zip(shapes, sizes, strict=True)])  # fmt: skip
    theta = minimize(loss, start, jac=True, method="L-BFGS-B", options={"maxiter": 3000}).x
    params = unpack(theta)
    layers = tuple((params[i], params[i + 1]) for i in range(0, len(params), 2))
    return mean, scale, layers


# -- threshold on the tuning set -------------------------------------------------------------

TUNE_CONDITIONS = (("clean", None), ("white", 20.0), ("white", 10.0), ("pink", 20.0), ("pink", 10.0))


def _tune_job(job: tuple[str, str, int, int, int]) -> list[list[Heard]]:
    """A tuning clip in every tuning condition: each of its utterances embedded."""
    global _EMBEDDING
    if _EMBEDDING is None:
        _EMBEDDING = SpeechEmbedding()
    text, voice, speed, pitch, seed = job
    samples = synthesise(text, voice, speed, pitch)
    out = []
    for kind, snr in TUNE_CONDITIONS:
        audio = mix(samples, kind, snr, 500_000 + seed)
        out.append([_heard(_EMBEDDING, u.samples) for u in find_utterances(audio)])
    return out


Tuning = list[tuple[str | None, list[list[Heard]]]]


def tuning_set(workers: int, cache: Path | None = None) -> Tuning:
    """The tuning clips' labels and embedded utterances, kept in ``cache`` under a name made from
    the clips themselves (a change of tuning voice or phrase is computed afresh, never reused)."""
    made = []
    seed = 0
    for voice, speed, pitch in itertools.product(tuning_voices(), TUNE_SPEEDS, TUNE_PITCHES):
        for label, text in [*SAY.items(), *((None, p) for p in TUNE_PHRASES)]:
            seed += 1
            made.append((label, (text, voice, speed, pitch, seed)))
    key = hashlib.sha256(json.dumps(made).encode()).hexdigest()[:16]
    path = cache / f"tune-{key}.pkl" if cache is not None else None
    if path is not None and path.exists():
        return pickle.loads(path.read_bytes())
    with ProcessPoolExecutor(workers) as pool:
        got = list(pool.map(_tune_job, [j for _, j in made], chunksize=8))
    tuning = [(label, g) for (label, _), g in zip(made, got, strict=True)]
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(pickle.dumps(tuning))
    return tuning


Heard6 = list[tuple[int, float]]  # each utterance's best class and its probability


def judged(classifier: Classifier, tuning: Tuning) -> list[tuple[str | None, list[Heard6]]]:
    """Every tuning utterance's best class and probability, computed once for the sweep."""
    out = []
    for label, conditions in tuning:
        per = []
        for utterances in conditions:
            best = []
            for frames, seconds in utterances:
                p = classifier.probabilities(pooled(frames.astype(np.float32), seconds))[0]
                best.append((int(np.argmax(p)), float(p.max())))
            per.append(best)
        out.append((label, per))
    return out


def decide(utterances: Heard6, thresholds: tuple[float, ...]) -> str:
    """What the benchmark's recognise_file would report: the first accepted utterance's command."""
    for best, p in utterances:
        if CLASSES[best] != "OTHER" and p >= thresholds[best]:
            return CLASSES[best]
    return ""


def score(judgements: list[tuple[str | None, list[Heard6]]], thresholds: tuple[float, ...]) -> dict:
    """Commands found and phrases taken for one (%), per tuning condition."""
    per = {}
    for c, (kind, snr) in enumerate(TUNE_CONDITIONS):
        hits = said = fa = phrases = 0
        for label, conditions in judgements:
            got = decide(conditions[c], thresholds)
            if label is None:
                phrases += 1
                fa += bool(got)
            else:
                said += 1
                hits += got == label
        name = kind if snr is None else f"{kind}_{snr:g}db"
        per[name] = {"commands": round(100 * hits / said, 1), "false_accepts": round(100 * fa / phrases, 1)}
    return per


GRID = tuple(float(t) for t in np.round(np.arange(0.30, 0.991, 0.01), 2))
NEVER = 2.0  # a threshold no probability reaches


def choose_thresholds(judgements: list[tuple[str | None, list[Heard6]]]) -> tuple[tuple[float, ...], dict]:
    """Each command's threshold, by a greedy search: all start at the top of ``GRID``; each move
    lowers one command's threshold to a lower place on the grid, the move that finds the most more
    tuning commands (summed over the conditions) per place gone down, as long as false accepts stay
    at or under ``TUNE_FALSE_ACCEPTS`` in every tuning condition; it stops when no move finds more.
    A word like one command ("yet" for YES) then keeps that command's threshold high and lets the
    others go down where they take nothing for a command."""

    def measure(places: list[int]) -> tuple[float, float, dict]:
        measured = score(judgements, (*(GRID[i] for i in places), NEVER))
        found = sum(m["commands"] for m in measured.values())
        return found, max(m["false_accepts"] for m in measured.values()), measured

    places = [len(GRID) - 1] * len(COMMANDS)
    found, _, measured = measure(places)
    while True:
        best: tuple[float, list[int], float, dict] | None = None
        for k in range(len(COMMANDS)):
            for step in range(1, places[k] + 1):
                trial = [p - step if i == k else p for i, p in enumerate(places)]
                more, worst, got = measure(trial)
                if worst > TUNE_FALSE_ACCEPTS:
                    break  # lower still only lets more in
                if more > found and (best is None or (more - found) / step > best[0]):
                    best = ((more - found) / step, trial, more, got)
        if best is None:
            return tuple(GRID[i] for i in places), measured
        _, places, found, measured = best


def main(out: Path | None = None, quick: bool = False, cache: Path | None = None, workers: int = 2) -> dict[str, Any]:
    _check_disjoint()
    start = time.perf_counter()
    voices = training_voices(8 if quick else TRAIN_VOICES)
    print(f"training voices ({len(voices)}): {' '.join(voices)}", flush=True)
    x, y, _voice = dataset(voices, workers, cache)
    print(f"{len(y)} training utterances ({np.bincount(y, minlength=len(CLASSES)).tolist()} per class), "
          f"{time.perf_counter() - start:.0f} s", flush=True)  # fmt: skip
    mean, scale, layers = fit(x, y)
    classifier = Classifier(mean, scale, layers, (0.5,) * len(COMMANDS), {})
    train_acc = float(np.mean(np.argmax(classifier.probabilities(x), 1) == y))
    print(f"fitted: training accuracy {100 * train_acc:.1f} %, {time.perf_counter() - start:.0f} s", flush=True)
    thresholds, measured = tuned_thresholds(classifier, workers, cache)
    named = dict(zip(COMMANDS, thresholds, strict=True))
    meta = {
        "trained_by": "python -m tests.bench train-speech" + (" --quick" if quick else ""),
        "voices": voices,
        "speeds": list(TRAIN_SPEEDS),
        "pitches": list(TRAIN_PITCHES),
        "copies": COPIES,
        "utterances": len(y),
        "per_class": np.bincount(y, minlength=len(CLASSES)).tolist(),
        "classes": list(CLASSES),
        "l2": L2,
        "hidden": HIDDEN,
        "training_accuracy": round(100 * train_acc, 2),
        **tuning_meta(measured),
        "espeak_ng": os.popen("espeak-ng --version").read().strip(),
    }  # fmt: skip
    final = Classifier(mean, scale, layers, thresholds, meta)
    path = out or (Path("commands-quick.npz") if quick else weights_path())  # a smoke run never replaces the shipped
    final.save(path)
    print(f"wrote {path} ({path.stat().st_size} bytes) in {time.perf_counter() - start:.0f} s", flush=True)
    return {"thresholds": named, "tuning": measured, "training_accuracy": train_acc}


def tuned_thresholds(classifier: Classifier, workers: int, cache: Path | None) -> tuple[tuple[float, ...], dict]:
    """``classifier``'s thresholds chosen on the tuning set, and what they find there."""
    thresholds, measured = choose_thresholds(judged(classifier, tuning_set(workers, cache)))
    named = dict(zip(COMMANDS, thresholds, strict=True))
    print(f"thresholds {named} on the tuning voices: {json.dumps(measured)}", flush=True)
    return thresholds, measured


def tuning_meta(measured: dict) -> dict[str, Any]:
    """How the thresholds were chosen, for the weights' ``meta``."""
    return {
        "threshold_rule": f"per command, greedy: most tuning commands with false accepts <= {TUNE_FALSE_ACCEPTS} % "
        "in every tuning condition",
        "tuning": {
            "voices": tuning_voices(),
            "speeds": list(TUNE_SPEEDS),
            "pitches": list(TUNE_PITCHES),
            "measured": measured,
        },
    }


def rethreshold(path: Path | None = None, cache: Path | None = None, workers: int = 2) -> dict[str, Any]:
    """Choose the thresholds of the weights at ``path`` (the shipped ones by default) again on the
    tuning set, keeping the network: what a change of tuning set or rule needs, without a refit."""
    _check_disjoint()
    path = path or weights_path()
    old = Classifier.load(path)
    thresholds, measured = tuned_thresholds(old, workers, cache)
    meta = {**old.meta, **tuning_meta(measured)}
    Classifier(old.mean, old.scale, old.layers, thresholds, meta).save(path)
    print(f"wrote {path}: thresholds {[round(t, 2) for t in old.thresholds]} -> {list(thresholds)}", flush=True)
    return {"thresholds": dict(zip(COMMANDS, thresholds, strict=True)), "tuning": measured}
