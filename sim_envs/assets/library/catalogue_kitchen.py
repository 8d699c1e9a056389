"""Groups of the taxonomy, and the categories of the kitchen and the dining table: drinkware,
tableware, cookware, cutlery and food.

Sizes are the longest side of real objects (metres), from common product dimensions.
"""

from __future__ import annotations

from sim_envs.assets.library.taxonomy import Category, Group

__all__ = ["GROUPS", "KITCHEN_CATEGORIES"]


def _g(name: str, synonyms: tuple[str, ...], parents: tuple[str, ...] = ("object",)) -> Group:
    return Group(name, synonyms, parents)


GROUPS: tuple[Group, ...] = (
    Group("object", ("thing", "item"), ()),
    _g("container", ("receptacle", "vessel")),
    _g("drinkware", ("cups and glasses", "beverage container"), ("container",)),
    _g("tableware", ("dishes", "dinnerware")),
    _g("kitchenware", ("kitchen utensil", "kitchen item")),
    _g("cookware", ("pots and pans", "cooking vessel"), ("kitchenware", "container")),
    _g("cutlery", ("silverware", "flatware", "utensil"), ("kitchenware", "tableware")),
    _g("appliance", ("household appliance", "kitchen appliance"), ("kitchenware", "electronics")),
    _g("food", ("something to eat", "groceries")),
    _g("fruit", ("fresh fruit", "produce"), ("food",)),
    _g("pastry", ("baked goods", "sweet"), ("food",)),
    _g("storage", ("storage container", "organiser"), ("container",)),
    _g("furniture", ("furnishing", "home furniture")),
    _g("seating", ("seat", "something to sit on"), ("furniture",)),
    _g("table", ("table furniture", "surface"), ("furniture",)),
    _g("decor", ("decoration", "ornament", "home decor")),
    _g("lighting", ("light", "light source")),
    _g("tool", ("implement", "equipment")),
    _g("hand tool", ("workshop tool", "diy tool"), ("tool",)),
    _g("toy", ("plaything", "children's toy")),
    _g("sports equipment", ("sports gear", "exercise equipment")),
    _g("office supply", ("office supplies", "desk item")),
    _g("stationery", ("writing supplies", "writing tool"), ("office supply",)),
    _g("reading material", ("reading matter", "publication")),
    _g("electronics", ("electronic device", "gadget")),
    _g("personal care", ("toiletries", "bathroom item")),
    _g("cleaning supply", ("cleaning product", "cleaning tool")),
    _g("household linen", ("textile", "soft furnishing")),
    _g("clothing", ("apparel", "clothes")),
    _g("safety equipment", ("safety gear", "road equipment")),
    _g("plant", ("houseplant", "greenery"), ("decor",)),
)
"""Inner nodes of the taxonomy (no instances of their own)."""

_W = ("white", "red", "blue", "green", "yellow", "black", "grey", "cream")

KITCHEN_CATEGORIES: tuple[Category, ...] = (
    Category("mug", ("coffee mug", "cup", "tea mug"), ("drinkware",), ("ceramic", "plastic", "metal"), _W, (0.08, 0.13),
             ("something to drink from", "a cup for hot coffee or tea"), ("mug_round", "mug_tall")),
    Category("cup", ("paper cup", "plastic cup", "beaker"), ("drinkware",), ("plastic", "paper", "ceramic"),
             ("white", "red", "blue", "green", "yellow", "pink", "orange"), (0.07, 0.13),
             ("something to drink from", "a cup for a cold drink"), ("cup_straight", "cup_tapered")),
    Category("drinking glass", ("tumbler", "water glass", "glass"), ("drinkware",), ("glass",), ("clear", "light blue", "green"),
             (0.08, 0.15), ("something to drink water from",), ("cup_straight", "cup_tapered")),
    Category("wine glass", ("goblet", "stemware", "champagne flute"), ("drinkware",), ("glass",), ("clear", "light blue", "maroon"),
             (0.15, 0.25), ("a glass for drinking wine",), ("goblet_round", "goblet_flute")),
    Category("bottle", ("water bottle", "glass bottle", "flask"), ("drinkware",), ("glass", "plastic"),
             ("clear", "green", "brown", "blue", "light blue"), (0.15, 0.32),
             ("something that holds a drink", "a container for liquids"), ("bottle_round", "bottle_wine", "bottle_squat")),
    Category("can", ("soda can", "tin can", "tin"), ("drinkware", "storage"), ("metal",),
             ("red", "silver", "blue", "green", "yellow", "black"), (0.10, 0.16),
             ("a can of soda to drink", "a tin that keeps food or drink"), ("can",)),
    Category("teapot", ("tea pot", "tea server"), ("tableware", "container"), ("ceramic", "metal"),
             ("white", "blue", "green", "red", "brown", "cream"), (0.15, 0.28), ("something to brew and pour tea",), ("teapot",)),
    Category("kettle", ("tea kettle", "water kettle"), ("cookware", "appliance"), ("metal", "plastic"),
             ("silver", "black", "white", "red"), (0.18, 0.30), ("something to boil water in",), ("kettle",)),
    Category("pitcher", ("jug", "carafe", "water jug"), ("tableware", "container"), ("ceramic", "glass", "plastic"),
             ("white", "clear", "blue", "cream"), (0.18, 0.30), ("something to pour water or juice from",), ("pitcher",)),
    Category("bowl", ("dish", "cereal bowl", "soup bowl"), ("tableware", "container"), ("ceramic", "wood", "plastic", "glass"),
             ("white", "blue", "red", "green", "cream", "brown", "black"), (0.10, 0.26),
             ("a dish for soup or cereal", "something to eat from"), ("bowl_round", "bowl_flared", "bowl_pedestal")),
    Category("plate", ("dinner plate", "dish", "platter"), ("tableware",), ("ceramic", "plastic"),
             ("white", "cream", "blue", "green", "red"), (0.15, 0.30),
             ("something to eat food from", "a dish to serve a meal on"), ("plate_flat", "plate_deep")),
    Category("jar", ("jam jar", "mason jar", "canister"), ("storage",), ("glass", "ceramic", "plastic"),
             ("clear", "white", "red", "green", "brown"), (0.08, 0.22),
             ("a container to keep food in", "something to store jam or cookies"), ("jar_wide", "jar_tall")),
    Category("salt shaker", ("pepper shaker", "salt cellar", "cruet"), ("tableware",), ("glass", "ceramic", "metal", "plastic"),
             ("white", "clear", "silver", "black"), (0.06, 0.11), ("something to sprinkle salt on food",), ("shaker_round", "shaker_hex")),
    Category("pepper mill", ("pepper grinder", "spice mill"), ("kitchenware",), ("wood", "metal"), ("brown", "black", "silver", "tan"),
             (0.14, 0.30), ("something to grind pepper",), ("mill",)),
    Category("cooking pot", ("stockpot", "pot", "casserole"), ("cookware",), ("metal", "ceramic"), ("silver", "black", "red", "grey"),
             (0.18, 0.34), ("something to cook soup in", "a pot to boil pasta"), ("pot_handles",)),
    Category("saucepan", ("sauce pan", "milk pan"), ("cookware",), ("metal",), ("silver", "black", "grey", "red"),
             (0.25, 0.42), ("a small pot with a long handle to heat sauce",), ("saucepan",)),
    Category("frying pan", ("skillet", "frypan"), ("cookware",), ("metal",), ("black", "silver", "grey"), (0.30, 0.50),
             ("something to fry eggs in",), ("frying_pan",)),
    Category("cutting board", ("chopping board", "breadboard"), ("kitchenware",), ("wood", "plastic"), ("tan", "brown", "white", "green"),
             (0.25, 0.45), ("a board to chop vegetables on",), ("cutting_board",)),
    Category("rolling pin", ("pastry roller", "dough roller"), ("kitchenware",), ("wood",), ("tan", "brown", "beige"), (0.30, 0.48),
             ("something to roll out dough",), ("rolling_pin",)),
    Category("toaster", ("bread toaster", "pop-up toaster"), ("appliance",), ("metal", "plastic"), ("silver", "white", "red", "black"),
             (0.22, 0.32), ("something to toast bread",), ("toaster",)),
    Category("spoon", ("tablespoon", "teaspoon", "soup spoon"), ("cutlery",), ("metal", "wood", "plastic"), ("silver", "brown", "white"),
             (0.12, 0.22), ("something to eat soup with", "something to stir with"), ("spoon",)),
    Category("fork", ("dinner fork", "table fork"), ("cutlery",), ("metal", "plastic"), ("silver", "white", "black"), (0.15, 0.21),
             ("something to eat food with",), ("fork",)),
    Category("knife", ("table knife", "kitchen knife", "blade"), ("cutlery",), ("metal",), ("silver", "black"), (0.18, 0.30),
             ("something to cut food with",), ("knife",)),
    Category("spatula", ("turner", "flipper", "egg slice"), ("kitchenware",), ("plastic", "metal", "wood"), ("black", "red", "silver", "brown"),
             (0.25, 0.35), ("something to flip pancakes with",), ("spatula",)),
    Category("apple", ("red apple", "green apple"), ("fruit",), ("organic",), ("red", "green", "yellow"), (0.06, 0.10),
             ("a fruit to eat", "a healthy snack"), ("fruit_round",)),
    Category("orange", ("mandarin", "tangerine", "citrus"), ("fruit",), ("organic",), ("orange", "yellow"), (0.06, 0.10),
             ("a citrus fruit to eat", "fruit to squeeze for juice"), ("fruit_round", "ball_squashed")),
    Category("pear", ("conference pear", "nashi"), ("fruit",), ("organic",), ("green", "yellow", "brown"), (0.08, 0.13),
             ("a sweet fruit to eat",), ("fruit_pear",)),
    Category("lemon", ("lime", "citron"), ("fruit",), ("organic",), ("yellow", "green"), (0.06, 0.10),
             ("a sour citrus fruit", "something to squeeze over fish"), ("fruit_oval",)),
    Category("donut", ("doughnut", "ring doughnut"), ("pastry",), ("organic",), ("brown", "pink", "tan", "cream"), (0.07, 0.12),
             ("a sweet pastry to eat",), ("donut",)),
)
"""Kitchen and dining categories."""
