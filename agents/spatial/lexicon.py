"""Words of spatial questions: tokens, word classes, relation-word typo repair, noun-phrase chunks.

The meaning-based parser (:mod:`agents.spatial.semantic`) reads a question in three steps that
live here, none of which knows the eight comparators:

1. :func:`tokenize` - lower case, contractions expanded, ``'s`` split off, chat abbreviations
   spelled out ("u" -> "you"); punctuation kept as ``,`` (pause) and ``.`` (sentence end).
2. :func:`repair_typos` - a token that is not a word the tokenizer of the text tower knows is
   replaced by the relation/function word at Damerau-Levenshtein distance 1 ("lfet" -> "left",
   "teh" -> "the"); run-together relation words are split ("ontop" -> "on top"). Object names
   are never touched: only words of :data:`RELATION_VOCABULARY` are targets, and a token the
   tower's word list knows (a real word) is kept, except the few real-word slips of function
   words in :data:`REAL_WORD_SLIPS`.
3. :func:`chunk` - the noun phrases of one clause, by word class: a phrase starts at a
   determiner (or a bare content word) and runs over content words and modifiers; relation
   words, auxiliaries, prepositions and pronouns end it. The clause with each phrase replaced
   by ``X``/``Y``/... is its *skeleton*, e.g. ``is X further left than Y``.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass

from agents.spatial.grammar import CONTRACTIONS

__all__ = [
    "DETERMINERS",
    "AUXILIARIES",
    "PRONOUNS",
    "WH_WORDS",
    "CONJUNCTIONS",
    "PREPOSITIONS",
    "FUNCTION_WORDS",
    "RELATION_WORDS",
    "MODIFIERS",
    "BASE_VERBS",
    "NOUN_HEADS",
    "DO_SUPPORT",
    "INQUIRY_VERBS",
    "RELATION_VOCABULARY",
    "REAL_WORD_SLIPS",
    "SELF_TOKEN",
    "Phrase",
    "PLACEHOLDERS",
    "tokenize",
    "repair_typos",
    "split_pieces",
    "strip_lead_in",
    "chunk",
    "looks_like_participle",
    "skeleton",
    "damerau_distance",
]

SELF_TOKEN = "<self>"
"""The token that stands for a self-reference ("me", "where I am") after :func:`tokenize`."""

# --- word classes ---------------------------------------------------------------------------

DETERMINERS = frozenset(
    "the a an this that these those my your our their his her its some any".split()
)
AUXILIARIES = frozenset(
    "is are was were be been being am do does did has have had will would can could should "
    "may might must shall not".split()
)
PRONOUNS = frozenset(
    "i you we it they me us them he she him one anyone someone anybody somebody something "
    "anything everything nothing there here".split()
)
WH_WORDS = frozenset("how what which where who whom whose whether if why when".split())
CONJUNCTIONS = frozenset("and or but than then so because since as while although though".split())
PREPOSITIONS = frozenset(
    "of on in inside into onto to from at by for with within without under underneath beneath "
    "below above over atop upon near beside besides next between among behind around across "
    "against toward towards off up down out away apart along past via like".split()
)
# Words that carry the relation (or hedge it). Never part of an object name, except as a
# modifier right after a determiner ("the big box", "the left cabinet", "the top drawer").
RELATION_WORDS = frozenset(
    """
    left right leftward leftwards rightward rightwards lefthand righthand hand side sides top
    bottom front back middle centre center
    far farther further farthest furthest close closer closest near nearer nearest distant adjacent
    distance distances gap separation spacing space room length long apart away
    big bigger biggest large larger largest small smaller smallest tall taller short shorter
    wide wider narrow narrower huge tiny little massive enormous giant bulky bulkier tinier
    huger longer greater less more much lot size sized volume footprint compared comparison
    relative versus vs dwarf dwarfs dwarfed tower towers towering
    fit fits fitting fitted contain contains containing contained hold holds holding held
    support supports supporting supported carry carries carrying enough capable able possible
    inside underneath beneath below above atop upon onto within neath
    placed put stored kept located situated positioned set sitting sits sit sat resting rests
    rest lying lies lie laid standing stands stacked piled perched balanced draped hung hanging
    hangs tucked hidden hiding stuck packed enclosed left sleeping leaning mounted parked thrown flung strewn
    go goes going slide squeeze stuff store keep pack place
    anywhere somewhere everywhere still currently really actually exactly just now already
    also right roughly approximately about precisely
    separate separates separating separated lie
    take takes taking occupy occupies occupying
    """.split()
)
# Modifiers that may open a noun phrase after a determiner ("the big box", "the left cabinet").
MODIFIERS = frozenset(
    "left right top bottom front back middle centre center big small little large tall short "
    "wide narrow huge tiny long giant massive enormous side near far upper lower".split()
)
# Base verbs that end the subject after do-support or a modal ("does the rack stand ...").
BASE_VERBS = frozenset(
    "stand sit lie rest hang lean go belong stay look seem appear fit take have hold contain "
    "need fall".split()
)
# Relation words and inquiry verbs that are also nouns heading a compound object name.
NOUN_HEADS = frozenset("tower stand rest set pack space room measure figure".split())
"""Words that end an object name when they follow a content word ("jenga tower", "umbrella
stand", "foot rest", "ice pack", "storage space", "living room", "tape measure", "action
figure", "knife set"), although they also carry a relation or an inquiry elsewhere ("towers
over", "figure out"). Under do-support or a modal, the subject's last such word is its verb
instead ("does the wardrobe tower over the bed"), unless a verb follows it ("can the jenga tower
fit ..."). Known ambiguity: "is the frame set on the shelf" reads "frame set" as the name."""
DO_SUPPORT = frozenset("does do did will would can could should might may".split())
"""Openers after which the subject is followed by a base verb ("does the rug look ...")."""
# -ing words that are nouns; any other -ing word of 6+ letters is read as a verb/modifier.
ING_NOUNS = frozenset(
    """painting ceiling building clothing railing bedding drawing wedding stuffing icing frosting
    seating lighting dressing pudding stocking carving ring string king wing spring swing sling
    thing sibling duckling dumpling awning tubing padding filling booking heating plumbing
    shelving flooring siding fencing roofing decking ceiling evening morning""".split()
)
INQUIRY_VERBS = frozenset(
    "tell check see look confirm verify know say guess estimate measure determine find figure "
    "show give let wonder wondering think ask calculate compute work".split()
)

FUNCTION_WORDS = DETERMINERS | AUXILIARIES | PRONOUNS | WH_WORDS | CONJUNCTIONS | PREPOSITIONS

RELATION_VOCABULARY = frozenset(
    FUNCTION_WORDS | RELATION_WORDS
    | {"underneath", "inside", "whether", "which", "please", "distance", "between", "smaller",
       "bigger", "larger", "taller", "wider", "shorter", "narrower", "resting", "next", "how",
       "many", "much", "from", "the"}
)
"""Targets of typo repair: function words and the words that carry a spatial relation."""

REAL_WORD_SLIPS = {"form": "from", "fro": "for", "ot": "to", "fo": "of", "fra": "far", "wich": "which"}
"""Real words that are, in a question, almost always a slip of a function word."""

_ABBREVIATIONS = {"u": "you", "ur": "your", "pls": "please", "plz": "please", "thx": "thanks", "r": "are"}

_CONTRACTIONS = CONTRACTIONS + (
    (r"\bcannot\b", "can not"),
    (r"\b(i|you|we|they)'ll\b", r"\1 will"),
)
_TOKEN = re.compile(r"[a-z0-9]+(?:'s)?|[,;:]|\s[-\u2013\u2014]+\s|[?!.]+")


def tokenize(text: str) -> list[str]:
    """Lower-case word tokens of ``text``; ``,`` marks a pause and ``.`` a sentence end.

    ``"Is the mug to the laptop's left??"`` -> ``["is", "the", "mug", "to", "the", "laptop",
    "'s", "left", "."]``. Hyphenated words are split ("left-hand" -> "left", "hand").
    """
    text = text.lower().replace("\u2019", "'").replace("\u2018", "'")
    for pattern, repl in _CONTRACTIONS:
        text = re.sub(pattern, repl, text)
    text = re.sub(r"(?<=[a-z])-(?=[a-z])", " ", text)
    tokens: list[str] = []
    for tok in _TOKEN.findall(" " + text + " "):
        tok = tok.strip()
        if tok in (",", ";", ":") or (tok and tok[0] in "-\u2013\u2014"):
            tokens.append(",")
        elif tok and tok[0] in "?!.":
            tokens.append(".")
        elif tok.endswith("'s") and len(tok) > 2:
            tokens += [tok[:-2], "'s"]
        elif tok:
            tokens.append(_ABBREVIATIONS.get(tok, tok))
    return tokens


# --- typo repair ----------------------------------------------------------------------------


def damerau_distance(a: str, b: str) -> int:
    """Optimal-string-alignment edit distance (insert, delete, substitute, swap neighbours)."""
    prev2: list[int] | None = None
    prev = list(range(len(b) + 1))
    for i in range(1, len(a) + 1):
        cur = [i] + [0] * len(b)
        for j in range(1, len(b) + 1):
            cost = a[i - 1] != b[j - 1]
            cur[j] = min(prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + cost)
            if prev2 is not None and i > 1 and j > 1 and a[i - 1] == b[j - 2] and a[i - 2] == b[j - 1]:
                cur[j] = min(cur[j], prev2[j - 2] + 1)
        prev2, prev = prev, cur
    return prev[-1]


@functools.lru_cache(maxsize=4096)
def _nearest_relation_word(token: str) -> str | None:
    best = None
    for word in sorted(RELATION_VOCABULARY):
        if abs(len(word) - len(token)) > 1 or len(word) < 3:
            continue
        if damerau_distance(token, word) == 1:
            # a dropped or swapped letter is the likeliest slip ("nxt" -> "next", not "not")
            dropped = len(word) == len(token) + 1 and _is_subsequence(token, word)
            key = (word[0] != token[0], not (dropped or sorted(word) == sorted(token)), word)
            if best is None or key < best[0]:
                best = (key, word)
    return None if best is None else best[1]


_NOUN_LIKE = frozenset(
    "top bottom side sides front back middle room space gap size hand lot set rest store pack place keep "
    "hold stuff tower dwarf lie length".split()
)


def _is_subsequence(short: str, long: str) -> bool:
    it = iter(long)
    return all(ch in it for ch in short)


def repair_typos(tokens: list[str], known_words: frozenset[str]) -> list[str]:
    """Replace misspelt relation/function words (see the module doc); object names stay.

    ``known_words`` is the set of real words (the text tower's word-piece vocabulary): a token in
    it is kept as written, apart from :data:`REAL_WORD_SLIPS` in function-word position and
    "then" after a comparative ("wider then" -> "wider than").
    """
    out: list[str] = []
    i = 0
    while i < len(tokens):
        tok = tokens[i]
        nxt = tokens[i + 1] if i + 1 < len(tokens) else ""
        if not tok.isalpha() or tok in RELATION_VOCABULARY:
            if tok == "then" and out and out[-1].endswith("er"):
                tok = "than"
            out.append(tok)
            i += 1
            continue
        if nxt.isalpha() and (tok + nxt) in RELATION_VOCABULARY and tok + nxt not in known_words and len(tok + nxt) >= 6:
            out.append(tok + nxt)  # "under neath" -> "underneath"
            i += 2
            continue
        prev = out[-1] if out else ""
        in_phrase = prev in DETERMINERS or (prev.isalpha() and prev not in RELATION_VOCABULARY)
        next_is_function = nxt in FUNCTION_WORDS or nxt in ("", ",", ".")
        if in_phrase and not (nxt in FUNCTION_WORDS and nxt not in DETERMINERS or nxt in ("hand", "side")) \
                and not (prev not in DETERMINERS and next_is_function):
            out.append(tok)  # inside a noun phrase: an object name, never corrected
        elif tok in REAL_WORD_SLIPS and (nxt in DETERMINERS or nxt in ("is", "are", SELF_TOKEN, "me") or prev == "how"):
            out.append(REAL_WORD_SLIPS[tok])
        elif tok not in known_words and len(tok) >= 3:
            fixed = _nearest_relation_word(tok)
            if fixed in _NOUN_LIKE and nxt != "of":
                fixed = None  # "the mop to the left": "top" would need "of" after it
            split = _split_run_together(tok)
            if fixed is not None:
                out.append(fixed)
            elif split is not None:
                out.extend(split)
            else:
                out.append(tok)
        else:
            out.append(tok)
        i += 1
    return out


def _split_run_together(token: str) -> list[str] | None:
    for k in range(2, len(token) - 1):
        head, tail = token[:k], token[k:]
        if head in RELATION_VOCABULARY and tail in RELATION_VOCABULARY and len(tail) >= 3:
            return [head, tail]
    return None


# --- pieces and lead-ins --------------------------------------------------------------------


def split_pieces(tokens: list[str]) -> list[list[str]]:
    """Split at sentence ends and dashes (already ``,``/``.`` tokens) into sentences."""
    pieces: list[list[str]] = [[]]
    for tok in tokens:
        if tok == ".":
            pieces.append([])
        else:
            pieces[-1].append(tok)
    return [p for p in pieces if any(t != "," for t in p)]


_GREETINGS = frozenset(
    "hey hi hello ok okay so robot please sorry excuse well yo also quick question one just "
    "honestly basically now oh um uh".split()
)
_WRAPPER_START = frozenset({"can", "could", "would", "will", "do", "you", "please", "i", "we"})


def strip_lead_in(tokens: list[str]) -> list[str]:
    """Drop greetings, comma-fenced openers without a determiner ("From where I stand,") and
    inquiry wrappers ("can you tell me whether", "I was wondering if") from the front."""
    toks = [t for t in tokens]
    while toks and toks[0] == ",":
        toks = toks[1:]
    changed = True
    while changed and toks:
        changed = False
        # an opener fenced by a comma that names no object: "Sorry to bother you, but"
        if "," in toks:
            k = toks.index(",")
            head = toks[:k]
            if head and not any(t in DETERMINERS or t == SELF_TOKEN for t in head) and len(head) <= 7 \
                    and not any(t in ("between", "compared", "which") for t in head) and len(toks) > k + 2:
                toks = toks[k + 1:]
                if toks and toks[0] == "but":
                    toks = toks[1:]
                changed = True
                continue
        if toks[0] in _GREETINGS and len(toks) > 2:
            toks = toks[1:]
            changed = True
            continue
        n = _wrapper_length(toks)
        if n:
            toks = toks[n:]
            changed = True
    return toks


def _wrapper_length(toks: list[str]) -> int:
    """Length of an inquiry wrapper at the front ("could you please check if"), or 0."""
    i = 0
    n = len(toks)
    if i < n and toks[i] in ("can", "could", "would", "will") and i + 1 < n and toks[i + 1] == "you":
        i += 2
    elif i < n and toks[i] in ("do", "does") and i + 1 < n and toks[i + 1] in ("you", "anyone", "anybody"):
        i += 2
    elif i < n and toks[i] in ("i", "we"):
        j = i + 1
        while j < n and toks[j] in ("would", "like", "want", "need", "am", "are", "was", "were", "to", "just", "really",
                                    "wanted", "trying", "wonder", "wondering", "wish", "know", "curious"):
            j += 1
        if j == i + 1 or not any(t in ("know", "wonder", "wondering", "curious", "check", "see", "find") for t in toks[i + 1:j + 1]):
            return 0
        i = j
    start = i
    while i < n and toks[i] in ("please", "just", "quickly"):
        i += 1
    if i < n and toks[i] in INQUIRY_VERBS:
        i += 1
        while i < n and toks[i] in ("me", "us", "out", "for", "please", "up", "know"):
            i += 1
    elif i == start and i == 0:
        return 0
    while i < n and toks[i] in ("whether", "if", "that", ","):
        i += 1
    # never eat the whole question or the start of a noun phrase
    if i >= n - 2:
        return 0
    return i


# --- chunking -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Phrase:
    """One noun phrase of a clause: token span ``[start, end)`` and its object name."""

    start: int
    end: int
    name: str
    """The phrase without its leading determiner ("the red mug" -> "red mug"); :data:`SELF_TOKEN` for me/here."""
    bare: bool
    """Whether the phrase had no determiner (a bare word run, possibly a verb)."""


PLACEHOLDERS = ("X", "Y", "Z", "W", "V", "U")
"""Placeholders of the phrases in a skeleton, in order of appearance."""


def _is_content(tok: str) -> bool:
    """Whether ``tok`` may be part of an object name (a noun or adjective, not a relation word)."""
    if not tok.isalnum() or tok in FUNCTION_WORDS or tok in RELATION_WORDS or tok in INQUIRY_VERBS:
        return False
    return not looks_like_participle(tok)


_ED_NOUN_ENDINGS = ("bed", "eed", "sled")  # "waterbed", "tweed", "bobsled"; "-shed" is mostly a verb ("stashed")


def looks_like_participle(tok: str) -> bool:
    """An -ing word of 6+ letters that is not a noun ("leaning"), or an -ed word of 5+ letters
    that is not a relation word nor a noun ending ("sealed", "stashed"; not "daybed"): a verb or
    a modifier, which may open an object name ("the stuffed toy") but never end one."""
    return (len(tok) > 5 and tok.endswith("ing") and tok not in ING_NOUNS) or (
        len(tok) > 4 and tok.endswith("ed") and tok not in RELATION_WORDS and not tok.endswith(_ED_NOUN_ENDINGS))


def _is_modifier(tok: str) -> bool:
    return tok in MODIFIERS or looks_like_participle(tok)


_RELATION_NOUNS = frozenset("distance distances gap separation spacing space room size volume length".split())


def _is_head(tokens: list[str], j: int, start: int) -> bool:
    """Whether ``tokens[j]`` is a :data:`NOUN_HEADS` noun ending a name that starts at ``start``."""
    return tokens[j] in NOUN_HEADS and j > start and _is_content(tokens[j - 1])


def chunk(tokens: list[str]) -> list[Phrase]:
    """Noun phrases of one clause, in order (see the module doc).

    A determiner opens a phrase; modifiers may follow it only when a content word comes after
    them ("the big box" but not "the left of"); "of" joins two phrases when the first ends in a
    content word ("glass of water", not "left of"); a word of :data:`NOUN_HEADS` right after a
    content word stays in the phrase ("the jenga tower", "the tape measure"). After do-support or
    a modal ("does the rug look larger", "does the wardrobe tower over"), a base verb or noun head
    at the end of the first phrase is left out of it, unless a base verb follows ("can the jenga
    tower fit").
    """
    phrases: list[Phrase] = []
    i, n = 0, len(tokens)
    do_support = bool(tokens) and tokens[0] in DO_SUPPORT
    while i < n:
        tok = tokens[i]
        if tok == SELF_TOKEN:
            phrases.append(Phrase(i, i + 1, SELF_TOKEN, False))
            i += 1
            continue
        det = tok in DETERMINERS
        j = i + 1 if det else i
        start = j
        while j < n:
            t = tokens[j]
            nxt = tokens[j + 1] if j + 1 < n else ""
            if nxt == "than" or (nxt == "enough" and j > start):
                break  # a comparative ("hotter than", "wide enough"), not part of the name
            if _is_content(t) or _is_head(tokens, j, start):
                j += 1
            elif t == "can" and j > start and not (_is_content(nxt) or nxt in DETERMINERS or nxt in PRONOUNS
                                                    or nxt in BASE_VERBS or nxt in RELATION_WORDS or nxt == "be"):
                j += 1  # "the trash can", "a tin can"
            elif _is_modifier(t) and j + 1 < n and (_is_content(tokens[j + 1]) or _is_modifier(tokens[j + 1])) \
                    and tokens[j + 1] not in ("hand", "side"):
                j += 1
            elif t == "of" and j > start and _is_content(tokens[j - 1]) and j + 1 < n and (
                    _is_content(tokens[j + 1]) or (tokens[j + 1] in ("the", "a", "an") and j + 2 < n and _is_content(tokens[j + 2]))):
                j += 1 if _is_content(tokens[j + 1]) else 2
            else:
                break
        end = j
        while end > start and not (_is_content(tokens[end - 1]) or tokens[end - 1] == "can"
                                   or _is_head(tokens, end - 1, start)):
            end -= 1
        if end > start and end < n and tokens[end] in _RELATION_NOUNS and (det or end - start == 1):
            i = end  # "the shortest distance": a modifier of the relation noun, not an object
            continue
        if end > start:
            if do_support and not phrases and end - start >= 2 and tokens[end - 1] in BASE_VERBS | NOUN_HEADS \
                    and not (end < n and tokens[end] in BASE_VERBS):
                end -= 1  # "does the coat rack stand ..." -> the base verb is not part of the subject
            phrases.append(Phrase(i if det else start, end, " ".join(tokens[start:end]), not det))
            i = end
        else:
            i += 1
    return phrases


def skeleton(tokens: list[str], phrases: list[Phrase]) -> str:
    """``tokens`` with each of ``phrases`` replaced by its placeholder (X, Y, ...)."""
    out: list[str] = []
    k = 0
    for idx, p in enumerate(phrases):
        out += tokens[k:p.start]
        out.append(PLACEHOLDERS[min(idx, len(PLACEHOLDERS) - 1)])
        k = p.end
    out += tokens[k:]
    return " ".join(out).replace(" 's", "'s").replace(" ,", ",")
