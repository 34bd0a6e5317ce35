"""Which object a person means: the words people use for the catalog's object types.

A question names an object in a person's words: "apples", "the TV", "my mobile phone", "the kitchen
counter", "sliced tomato". `meanings(phrase)` lists what the phrase may mean, most literal first, as
`Meaning`s that the oracle tries in order against the objects of the scene (answers.resolve_object):

1. the phrase as typed: an object's own noun or type name ("counter", "CounterTop"), then the
   catalog's other nouns for a type ("couch" for Sofa: `noun_variants_alfred` in
   dialfred_sim/data/object_types.csv, ALFRED's annotators' words), then the everyday names below;
2. the same in the singular ("apples" -> "apple", "knives" -> "knife", "cell phones" -> "cell phone");
3. the same without a leading determiner or plain adjective ("my phone", "the small bowl");
4. for a whole food that has been sliced, its slices ("tomato" when only tomato slices are left).

Sources: the catalog's nouns (programmatic, so every type and every ALFRED variant is covered);
the names of what Slice makes, built from the catalog's sliceable types ("sliced apple", "apple
slices", "slice of bread", "piece of potato"); and `EVERYDAY_NAMES`, a small hand-made table of
common English names the ALFRED annotators did not use (each maps to catalog nouns, so it cannot
name anything the catalog does not). Everything here is plain Python over the catalog.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass

from dialfred_sim.catalog import load_catalog

# Everyday names -> catalog nouns, tried in this order (hand-made: common British and American
# English for household objects; where a name fits two types, both, the likelier first).
EVERYDAY_NAMES: dict[str, tuple[str, ...]] = {
    # television, remote
    'tv': ('television',), 'telly': ('television',), 'tv set': ('television',), 'television set': ('television',),
    'flat screen': ('television',), 'flatscreen': ('television',),
    'tv remote': ('remote control',), 'television remote': ('remote control',), 'clicker': ('remote control',),
    'tv controller': ('remote control',), 'remote controller': ('remote control',),
    'television stand': ('tv stand',), 'tv cabinet': ('tv stand',), 'tv table': ('tv stand',),
    'tv unit': ('tv stand',), 'media console': ('tv stand',),
    # phones, computers, books
    'mobile': ('cell phone',), 'mobile phone': ('cell phone',), 'cellular phone': ('cell phone',),
    'iphone': ('cell phone',), 'telephone': ('cell phone',),
    'notebook': ('book', 'laptop'), 'notebook computer': ('laptop',), 'laptop computer': ('laptop',),
    'magazine': ('newspaper', 'book'),
    # kitchen fixtures
    'kitchen counter': ('counter',), 'kitchen countertop': ('counter',), 'worktop': ('counter',),
    'kitchen worktop': ('counter',), 'work surface': ('counter',), 'bathroom counter': ('counter',),
    'kitchen sink': ('sink',), 'bathroom sink': ('sink',), 'wash basin': ('sink',), 'washbasin': ('sink',),
    'tap': ('faucet',), 'water tap': ('faucet',),
    'refrigerator freezer': ('fridge',), 'icebox': ('fridge',),
    'microwave oven': ('microwave',), 'hob': ('stove burner',), 'cooker': ('stove burner',),
    'stove top': ('stove burner',), 'stovetop': ('stove burner',), 'gas ring': ('stove burner',),
    'kitchen cabinet': ('cabinet',), 'cupboard door': ('cabinet',),
    # bins
    'dustbin': ('garbage can',), 'rubbish bin': ('garbage can',), 'waste bin': ('garbage can',),
    'litter bin': ('garbage can',), 'recycling bin': ('garbage can',),
    # furniture
    'settee': ('sofa',), 'easy chair': ('armchair',), 'reclining chair': ('armchair',),
    'bedside table': ('side table',), 'night table': ('side table',), 'bedside cabinet': ('side table',),
    'dinner table': ('dining table',), 'writing desk': ('desk',),
    'chest': ('dresser',), 'bookshelf': ('shelf',), 'bookcase': ('shelf',), 'pouf': ('ottoman',),
    'table lamp': ('desk lamp',), 'reading lamp': ('desk lamp',), 'standing lamp': ('floor lamp',),
    'standard lamp': ('floor lamp',),
    'potted plant': ('house plant',), 'plant': ('house plant',),
    'picture': ('painting', 'poster'), 'artwork': ('painting',),
    'teddy': ('teddy bear',), 'stuffed animal': ('teddy bear',), 'soft toy': ('teddy bear',),
    'laundry basket': ('laundry hamper',), 'hamper': ('laundry hamper',), 'clothes hamper': ('laundry hamper',),
    # bathroom
    'loo': ('toilet',), 'toilet bowl': ('toilet',),
    'loo roll': ('toilet paper',), 'toilet tissue': ('toilet paper',), 'toilet brush': ('scrub brush',),
    'washcloth': ('cloth',), 'dishcloth': ('cloth',), 'tea towel': ('hand towel', 'cloth'),
    'dish towel': ('hand towel', 'cloth'), 'bath towel': ('towel',), 'towel rail': ('towel holder',),
    'towel rack': ('towel holder',),
    # kitchenware and small things
    'coffee mug': ('mug',), 'tea cup': ('cup',), 'teacup': ('cup',), 'drinking glass': ('cup',),
    'cooking pot': ('pot',), 'frypan': ('pan',), 'kitchen knife': ('knife',), 'chef knife': ('knife',),
    'chopping knife': ('knife',), 'table knife': ('butter knife', 'knife'), 'dinner plate': ('plate',),
    'salt cellar': ('salt shaker',), 'pepper pot': ('pepper shaker',), 'pepper grinder': ('pepper shaker',),
    'dish soap': ('soap bottle',), 'hand soap': ('soap bottle', 'soap bar'), 'liquid soap': ('soap bottle',),
    'cleaning spray': ('spray bottle',), 'spray can': ('spray bottle',), 'electric kettle': ('kettle',),
    'water bottle': ('bottle',), 'wine glass': ('cup',), 'keyring': ('key chain',), 'key ring': ('key chain',),
    'house keys': ('key chain',), 'bank card': ('credit card',), 'debit card': ('credit card',),
    'wristwatch': ('watch',), 'alarm': ('alarm clock',),
    'flower vase': ('vase',), 'paper towels': ('paper towel roll',), 'kitchen roll': ('paper towel roll',),
    'candlestick': ('candle',), 'ornament': ('statue',),
}

# Leading words that only say which one or what it is like ("my phone", "the small bowl"); dropped
# when the phrase with them names nothing.
MODIFIERS = frozenset(('the', 'a', 'an', 'my', 'your', 'our', 'his', 'her', 'their', 'this', 'that', 'these',
                       'those', 'some', 'any', 'one', 'small', 'little', 'big', 'large', 'tiny', 'huge', 'whole',
                       'entire', 'dirty', 'clean', 'washed', 'hot', 'warm', 'heated', 'cold', 'cool', 'chilled',
                       'open', 'opened', 'closed', 'empty', 'old', 'new'))

# Phrases for what slicing makes, from the whole food's nouns: '{n}' is one of them.
_SLICE_PATTERNS = ('sliced {n}', '{n} slice', 'slice of {n}', 'slices of {n}', 'piece of {n}', '{n} piece',
                   'cut {n}', 'chopped {n}', '{n} wedge')

_IRREGULAR = {'knives': 'knife', 'shelves': 'shelf', 'loaves': 'loaf', 'leaves': 'leaf', 'halves': 'half',
              'wolves': 'wolf', 'scarves': 'scarf', 'feet': 'foot', 'teeth': 'tooth', 'mice': 'mouse',
              'people': 'person', 'children': 'child', 'shoes': 'shoe', 'toes': 'toe', 'dice': 'die'}
_INVARIANT = frozenset(('news', 'series', 'species', 'lens', 'gas'))


def singular(word: str) -> str:
    """The singular of an English noun: 'apples' -> 'apple', 'knives' -> 'knife', 'glasses' -> 'glass',
    'dishes' -> 'dish', 'tomatoes' -> 'tomato', 'boxes' -> 'box', 'batteries' -> 'battery'. A word
    that is not a regular plural comes back unchanged ('glass', 'lettuce', 'tennis', 'cd')."""
    w = word.lower()
    if w in _IRREGULAR:
        return _IRREGULAR[w]
    if len(w) < 3 or w in _INVARIANT or w.endswith(('ss', 'us', 'is')) or not w.endswith('s'):
        return w
    if w.endswith('ies') and len(w) > 4:
        return w[:-3] + 'y'
    if w.endswith(('sses', 'shes', 'ches', 'xes', 'zes', 'oes')):
        return w[:-2]
    return w[:-1]


def words(phrase: str) -> tuple[str, ...]:
    """'Sink-Basin' -> ('sink', 'basin'); 'CounterTop' -> ('countertop',) (a type name is one word)."""
    return tuple(w for w in re.split(r'[\s_\-]+', phrase.lower()) if w)


@functools.lru_cache(maxsize=4096)
def key(phrase: str) -> str:
    """The phrase as compared: lower case without spaces, hyphens or underscores ('sinkbasin')."""
    return ''.join(words(phrase))


@functools.lru_cache(maxsize=4096)
def singular_key(phrase: str) -> str:
    """`key` of the phrase with every word in the singular ('cellphone' for 'cell phones')."""
    return ''.join(singular(w) for w in words(phrase))


@dataclass(frozen=True)
class Meaning:
    """One reading of a phrase: objects whose own noun or type name has this key (`by_name`, in
    the singular if `singular`), or objects of one of `types`."""

    by_name: str = ''
    singular: bool = False
    types: frozenset = frozenset()

    def matches(self, noun: str, type_name: str) -> bool:
        if self.by_name:
            k = singular_key if self.singular else key
            return self.by_name in (k(noun), k(type_name))
        return type_name in self.types


@functools.lru_cache(maxsize=1)
def _tables() -> tuple[dict, dict, dict, dict]:
    """(variant key -> types, singular variant key -> types, name key -> catalog phrases,
    singular name key -> catalog phrases) for the catalog's other nouns and the everyday names."""
    catalog = load_catalog()
    variants: dict[str, set] = {}
    variants_singular: dict[str, set] = {}
    for name, t in catalog.items():
        for noun in t.nouns:
            variants.setdefault(key(noun), set()).add(name)
            variants_singular.setdefault(singular_key(noun), set()).add(name)
    everyday: dict[str, tuple[str, ...]] = {}
    for _name, t in sorted(catalog.items()):
        if t.sliced_type and t.sliced_type in catalog:
            for noun in t.nouns:
                for pattern in _SLICE_PATTERNS:
                    everyday.setdefault(key(pattern.format(n=noun)), (catalog[t.sliced_type].noun,))
    for phrase, nouns in EVERYDAY_NAMES.items():
        everyday[key(phrase)] = nouns
    everyday_singular: dict[str, tuple[str, ...]] = {}
    for k, nouns in everyday.items():
        everyday_singular.setdefault(singular_key(k), nouns)
    freeze = lambda d: {k: frozenset(v) for k, v in d.items()}
    return freeze(variants), freeze(variants_singular), everyday, everyday_singular


def _literal(phrase: str) -> list[Meaning]:
    """What `phrase` names as typed: own noun / type name, catalog variant, everyday name (which
    names catalog nouns, read the same way); then all of that with every word in the singular on
    both sides ('apples' is an apple, and 'blind' is the catalog's 'blinds')."""
    variants, variants_singular, everyday, everyday_singular = _tables()
    k, sk = key(phrase), singular_key(phrase)
    out = [Meaning(by_name=k)]
    if k in variants:
        out.append(Meaning(types=variants[k]))
    out += _catalog_readings(everyday.get(k, ()))
    out.append(Meaning(by_name=sk, singular=True))
    if sk in variants_singular:
        out.append(Meaning(types=variants_singular[sk]))
    out += _catalog_readings(everyday_singular.get(sk, ()))
    return out


def _catalog_readings(nouns: tuple[str, ...]) -> list[Meaning]:
    """The readings of catalog nouns an everyday name stands for: own noun, then variant."""
    variants = _tables()[0]
    out = []
    for noun in nouns:
        out.append(Meaning(by_name=key(noun)))
        if key(noun) in variants:
            out.append(Meaning(types=variants[key(noun)]))
    return out


def _without_modifiers(phrase: str) -> str:
    ws = list(words(phrase))
    while len(ws) > 1 and ws[0] in MODIFIERS:
        ws.pop(0)
    return ' '.join(ws)


def _slices_of(readings: list[Meaning]) -> list[Meaning]:
    """For readings that name a whole sliceable food, its slices (what is left after a Slice)."""
    catalog = load_catalog()
    sliced = []
    for name, t in sorted(catalog.items()):
        if t.sliced_type and any(m.matches(t.noun, name) for m in readings):
            sliced.append(t.sliced_type)
    return [Meaning(types=frozenset(sliced))] if sliced else []


@functools.lru_cache(maxsize=2048)
def meanings(phrase: str) -> tuple[Meaning, ...]:
    """The readings of `phrase` (already stripped of punctuation and articles, lower case), most
    literal first; duplicates removed. Tried in order, the first one that names an object in the
    scene (in a task: one of the task's objects) is what the person meant."""
    readings = _literal(phrase)
    bare = _without_modifiers(phrase)
    if bare != ' '.join(words(phrase)):
        readings += _literal(bare)
    readings += _slices_of(readings)
    return tuple(dict.fromkeys(readings))
