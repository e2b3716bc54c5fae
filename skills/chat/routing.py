"""Which utterances are robot commands: they go to the mission, everything else to the chatbot.

The PeopleBot paper's recogniser knew five words: PHOTO, YES, WHATSUP, CANCEL and CIAO. Here
each is also a few natural phrasings ("take a picture of us", "what is there to see", "never
mind", "see you"), with polite words around them ("maya, could you take a photo please").

A command is the whole of the last sentence, not a word found anywhere: "yes, I like music"
is conversation, "Hi Maya! Take a photo of us." is PHOTO. A bare "yes" is always the command,
even when the chatbot had just asked a question: the mission's vocabulary comes first.
"""

from __future__ import annotations

import re

COMMANDS = ("PHOTO", "YES", "WHATSUP", "CANCEL", "CIAO")

_PICTURE = r"(?:photo|picture|pic|selfie|photograph|snapshot|foto)s?"
_PHRASES: dict[str, str] = {
    "PHOTO": "|".join(
        (
            rf"{_PICTURE}(?: time)?",
            rf"(?:take|snap|make|shoot|get|have|do) (?:a |an |our |my |us a |me a |one |some |another )?{_PICTURE}"
            r"(?: of (?:us|me|them|all of us|us all|my \w+|our \w+|the \w+))?(?: with (?:you|us|me))?(?: together)?",
            rf"(?:can|could|may) (?:we|i) (?:have|get|take) (?:a |our |one )?{_PICTURE}(?: with you)?",
            r"(?:say )?cheese",
        )
    ),
    "YES": "|".join(
        (
            r"yes|yeah|yep|yup|yas|sure(?: thing)?|of course|ok|okay|alright|all right|absolutely|affirmative",
            r"go ahead|go|do it|take it|shoot|lets do it|lets go",
            r"(?:i am |im |we are |were )?ready",
        )
    ),
    "WHATSUP": "|".join(
        (
            r"whats ?up|what is up|wh?assup|wazz?up|sup",
            r"whats (?:new|on|happening)|what is (?:new|on|happening)",
            r"what (?:is|s) there to (?:see|do)(?: here)?|what can (?:i|we) (?:see|do) here",
            r"tell (?:me|us) (?:more )?about (?:this place|the museum|the attraction|the exhibition|the exhibits|"
            r"the hall|this museum|it)",
            r"(?:show (?:me|us) |give (?:me|us) )?(?:some |more )?info(?:rmation)?",
        )
    ),
    "CANCEL": "|".join(
        (
            r"cancel(?: it| that| the photo| the picture)?|stop(?: it| that)?|abort",
            r"never ?mind|forget (?:it|that|about it)|no thanks|no thank you|not now|no (?:photo|picture)s?",
            r"(?:i|we) changed (?:my|our) minds?|dont|do not",
        )
    ),
    "CIAO": "|".join(
        (
            r"ciao|bye|bye bye|goodbye|good bye|farewell|cheerio|arrivederci|so long|take care",
            r"see (?:you|ya)(?: later| soon| around| next time)?|later",
            r"(?:i|we) (?:have to|must|need to|gotta|got to) (?:go|leave)(?: now)?",
            r"(?:i am|im|we are|were) (?:leaving|off)(?: now)?",
        )
    ),
}
# polite words that may come before or after a command phrase
_BEFORE = (
    r"(?:(?:hey|hi|hello|ok|okay|please|so|well|oh|maya|robot|now|and|thanks|thank you|then)\s+)*"
    r"(?:(?:can|could|would|will) you\s+(?:please\s+)?)?"
    r"(?:(?:i|we) (?:want|would like|d like|wanna) (?:to\s+)?)?"
    r"(?:(?:lets|let us)\s+)?"
)
_AFTER = r"(?:\s+(?:please|maya|now|then|thanks|thank you|for (?:me|us)|right now|again|robot))*"
_PATTERNS = {command: re.compile(rf"{_BEFORE}(?:{core}){_AFTER}") for command, core in _PHRASES.items()}
_FILLER = re.compile(r"(?:(?:please|thanks|thank you|maya|hey|hi|hello|wow|oh)\s*)+")  # a sentence of only these
_SENTENCES = re.compile(r"[.?!]+")
_NOT_WORD = re.compile(r"[^a-z0-9]+")


def normalise(text: str) -> str:
    """Lower case, apostrophes dropped (what's: whats), anything else that is not a letter a space."""
    text = text.lower().replace("\u2019", "'").replace("'", "")
    return _NOT_WORD.sub(" ", text).strip()


def route(text: str) -> str | None:
    """The command ``text`` says (one of COMMANDS), or None when it is conversation."""
    sentences = [normalise(s) for s in _SENTENCES.split(text)]
    sentences = [s for s in sentences if s and not _FILLER.fullmatch(s)]
    if not sentences:
        return None
    last = sentences[-1]
    for command, pattern in _PATTERNS.items():
        if pattern.fullmatch(last):
            return command
    return None
