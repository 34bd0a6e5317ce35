"""The registry of type names to shape builders, and `shape_for`, the one way to get a shape.

Every entry (builder, layout, default extents) fixes the geometry of the generated rooms and of
the shipped task data: change one and the rooms change.
"""

from __future__ import annotations

import functools
from typing import Callable, Optional

from ..geometry import ShapeSpec, Vec3
from .decor import (_curtains, _desk_lamp, _floor_lamp, _house_plant, _lamp, _mirror, _painting,
                    _poster, _television, _window)
from .fixtures import (_bathtub, _bathtub_basin, _coffee_machine, _faucet, _hand_towel_holder,
                       _light_switch, _shower_glass, _shower_head, _sink, _sink_basin,
                       _stove_burner, _stove_knob, _toaster, _toilet_paper_hanger, _towel_holder)
from .food import (_apple, _apple_sliced, _bread, _bread_sliced, _egg, _lettuce, _lettuce_sliced,
                   _potato, _potato_sliced, _tomato, _tomato_sliced)
from .furniture import (_arm_chair, _bed, _cart, _chair, _coffee_table, _counter_top, _desk,
                        _dining_table, _dresser, _footstool, _garbage_can, _laundry_hamper,
                        _laundry_hamper_lid, _ottoman, _shelf, _side_table, _sofa, _tv_stand)
from .household import (_alarm_clock, _baseball_bat, _basketball, _book, _boots, _cd, _cell_phone,
                        _cloth, _credit_card, _dish_sponge, _hand_towel, _key_chain, _newspaper,
                        _pillow, _plunger, _remote, _scrub_brush, _soap_bar, _statue, _teddy_bear,
                        _tennis_racket, _tissue_box, _towel, _watch, _watering_can)
from .kitchenware import (_bowl, _candle, _cup, _glassbottle, _kettle, _mug, _pan, _paper_towel,
                          _paper_towel_roll, _plate, _pot, _shaker, _soap_bottle, _spray_bottle,
                          _toilet_paper, _toilet_paper_roll, _vase, _wine_bottle)
from .openables import (_blinds, _box_container, _cabinet, _drawer, _fridge, _laptop, _microwave,
                        _safe, _shower_curtain, _shower_door, _toilet)
from .utensils import _butter_knife, _fork, _knife, _ladle, _pen, _spatula, _spoon

_MIN_EDGE = 0.004

_Builder = Callable[[float, float, float], ShapeSpec]


def _flat(d):  # pickupable lying down: longest edge along x, shortest up
    return d[0], d[1], d[2]


def _flat_wide(d):  # lying down, longest edge across (y): laptops, boxes
    return d[1], d[0], d[2]


def _up(d):  # standing: longest edge up
    return d[1], d[2], d[0]


def _panel(d):  # thin along x, standing: hanging towels, clocks
    return d[2], d[1], d[0]


def _wide(d):  # fixed object: long horizontal side along y (its front), height as given
    return min(d[0], d[1]), max(d[0], d[1]), d[2]


def _deep(d):  # fixed object that is deeper than wide (bed, toilet)
    return max(d[0], d[1]), min(d[0], d[1]), d[2]


_TYPES: dict[str, tuple[_Builder, Callable, Vec3]] = {
    # food
    'Apple': (_apple, _flat, (0.1, 0.1, 0.1)),
    'AppleSliced': (_apple_sliced, _flat, (0.09, 0.09, 0.012)),
    'Bread': (_bread, _flat, (0.29, 0.16, 0.14)),
    'BreadSliced': (_bread_sliced, _flat, (0.11, 0.11, 0.015)),
    'Egg': (_egg, _flat, (0.07, 0.05, 0.05)),
    'Lettuce': (_lettuce, _flat, (0.24, 0.15, 0.15)),
    'LettuceSliced': (_lettuce_sliced, _flat, (0.09, 0.06, 0.02)),
    'Potato': (_potato, _flat, (0.12, 0.08, 0.08)),
    'PotatoSliced': (_potato_sliced, _flat, (0.09, 0.05, 0.012)),
    'Tomato': (_tomato, _flat, (0.12, 0.12, 0.1)),
    'TomatoSliced': (_tomato_sliced, _flat, (0.1, 0.1, 0.01)),
    # kitchenware
    'Bowl': (_bowl, _flat, (0.19, 0.19, 0.09)),
    'ButterKnife': (_butter_knife, _flat, (0.27, 0.02, 0.01)),
    'Cup': (_cup, _up, (0.11, 0.11, 0.15)),
    'Fork': (_fork, _flat, (0.25, 0.03, 0.02)),
    'Glassbottle': (_glassbottle, _up, (0.11, 0.11, 0.25)),
    'Kettle': (_kettle, _flat, (0.21, 0.2, 0.19)),
    'Knife': (_knife, _flat, (0.33, 0.05, 0.01)),
    'Ladle': (_ladle, _flat, (0.27, 0.09, 0.06)),
    'Mug': (_mug, _flat, (0.11, 0.1, 0.09)),
    'Pan': (_pan, _flat, (0.43, 0.26, 0.05)),
    'PepperShaker': (lambda X, Y, Z: _shaker(X, Y, Z, True), _up, (0.07, 0.07, 0.11)),
    'Plate': (_plate, _flat, (0.24, 0.24, 0.02)),
    'Pot': (_pot, _flat, (0.4, 0.28, 0.16)),
    'SaltShaker': (lambda X, Y, Z: _shaker(X, Y, Z, False), _up, (0.07, 0.07, 0.11)),
    'Spatula': (_spatula, _flat, (0.3, 0.06, 0.02)),
    'Spoon': (_spoon, _flat, (0.21, 0.04, 0.02)),
    'WineBottle': (_wine_bottle, _up, (0.09, 0.09, 0.33)),
    # small household objects
    'AlarmClock': (_alarm_clock, _panel, (0.09, 0.18, 0.19)),
    'BaseballBat': (_baseball_bat, _flat, (0.96, 0.09, 0.08)),
    'BasketBall': (_basketball, _flat, (0.24, 0.24, 0.24)),
    'Book': (_book, _flat, (0.3, 0.22, 0.03)),
    'Boots': (_boots, _up, (0.28, 0.22, 0.52)),
    'Box': (_box_container, _flat_wide, (0.41, 0.45, 0.29)),
    'Candle': (_candle, _up, (0.05, 0.05, 0.13)),
    'CD': (_cd, _flat, (0.1, 0.1, 0.002)),
    'CellPhone': (_cell_phone, _flat, (0.16, 0.08, 0.01)),
    'Cloth': (_cloth, _flat, (0.21, 0.18, 0.02)),
    'CreditCard': (_credit_card, _flat, (0.09, 0.05, 0.002)),
    'DishSponge': (_dish_sponge, _flat, (0.14, 0.07, 0.03)),
    'HandTowel': (_hand_towel, _panel, (0.04, 0.13, 0.4)),
    'KeyChain': (_key_chain, _flat, (0.13, 0.07, 0.01)),
    'Laptop': (_laptop, _flat_wide, (0.3, 0.4, 0.3)),
    'Newspaper': (_newspaper, _flat, (0.33, 0.13, 0.03)),
    'PaperTowel': (_paper_towel, _up, (0.12, 0.12, 0.3)),
    'PaperTowelRoll': (_paper_towel_roll, _up, (0.08, 0.06, 0.21)),
    'Pen': (lambda X, Y, Z: _pen(X, Y, Z, False), _flat, (0.2, 0.012, 0.012)),
    'Pencil': (lambda X, Y, Z: _pen(X, Y, Z, True), _flat, (0.18, 0.01, 0.01)),
    'Pillow': (_pillow, _flat, (0.42, 0.34, 0.14)),
    'Plunger': (_plunger, _up, (0.15, 0.15, 0.54)),
    'RemoteControl': (_remote, _flat, (0.22, 0.07, 0.02)),
    'ScrubBrush': (_scrub_brush, _up, (0.13, 0.13, 0.48)),
    'SoapBar': (_soap_bar, _flat, (0.09, 0.05, 0.02)),
    'SoapBottle': (_soap_bottle, _up, (0.12, 0.09, 0.24)),
    'SprayBottle': (_spray_bottle, _up, (0.11, 0.03, 0.25)),
    'Statue': (_statue, _up, (0.21, 0.15, 0.34)),
    'TeddyBear': (_teddy_bear, _flat, (0.47, 0.47, 0.33)),
    'TennisRacket': (_tennis_racket, _flat, (0.65, 0.26, 0.04)),
    'TissueBox': (_tissue_box, _flat_wide, (0.15, 0.2, 0.1)),
    'ToiletPaper': (_toilet_paper, _flat, (0.12, 0.07, 0.07)),
    'ToiletPaperRoll': (_toilet_paper_roll, _up, (0.045, 0.045, 0.1)),
    'Towel': (_towel, _panel, (0.04, 0.41, 0.59)),
    'Vase': (_vase, _up, (0.18, 0.18, 0.24)),
    'Watch': (_watch, _flat, (0.08, 0.05, 0.04)),
    'WateringCan': (_watering_can, _flat, (0.27, 0.19, 0.15)),
    # openable furniture and appliances
    'Blinds': (_blinds, _wide, (0.03, 0.89, 1.3)),
    'Cabinet': (_cabinet, _wide, (0.32, 0.47, 0.66)),
    'Drawer': (_drawer, _wide, (0.34, 0.52, 0.19)),
    'Fridge': (_fridge, _wide, (0.72, 1.0, 1.87)),
    'Microwave': (_microwave, _wide, (0.36, 0.61, 0.35)),
    'Safe': (_safe, _wide, (0.5, 0.56, 0.51)),
    'ShowerCurtain': (_shower_curtain, _wide, (0.05, 1.2, 1.94)),
    'ShowerDoor': (_shower_door, _wide, (0.06, 0.91, 1.96)),
    'Toilet': (_toilet, _deep, (0.7, 0.53, 0.8)),
    # furniture
    'ArmChair': (_arm_chair, _wide, (0.88, 1.0, 0.91)),
    'Bed': (_bed, _deep, (2.34, 1.42, 0.91)),
    'Cart': (_cart, _wide, (0.45, 0.7, 0.85)),
    'Chair': (_chair, _wide, (0.54, 0.61, 0.95)),
    'CoffeeTable': (_coffee_table, _wide, (0.7, 1.17, 0.44)),
    'CounterTop': (_counter_top, _wide, (0.7, 1.87, 0.9)),
    'Desk': (_desk, _wide, (0.66, 1.57, 0.8)),
    'DiningTable': (_dining_table, _wide, (0.92, 1.47, 0.78)),
    'Dresser': (_dresser, _wide, (0.56, 1.52, 0.97)),
    'Footstool': (_footstool, _wide, (0.28, 0.28, 0.31)),
    'GarbageCan': (_garbage_can, _wide, (0.36, 0.43, 0.54)),
    'LaundryHamper': (_laundry_hamper, _wide, (0.44, 0.52, 0.74)),
    'LaundryHamperLid': (_laundry_hamper_lid, _wide, (0.44, 0.52, 0.04)),
    'Ottoman': (_ottoman, _wide, (0.52, 0.85, 0.43)),
    'Shelf': (_shelf, _wide, (0.27, 0.6, 0.23)),
    'SideTable': (_side_table, _wide, (0.37, 0.62, 0.67)),
    'Sofa': (_sofa, _wide, (0.93, 2.48, 0.96)),
    'TVStand': (_tv_stand, _wide, (0.6, 1.2, 0.73)),
    # kitchen and bathroom fixtures
    'Bathtub': (_bathtub, _wide, (1.13, 2.09, 0.6)),
    'BathtubBasin': (_bathtub_basin, _wide, (0.64, 1.71, 0.42)),
    'CoffeeMachine': (_coffee_machine, _wide, (0.43, 0.48, 0.44)),
    'Faucet': (_faucet, _wide, (0.23, 0.32, 0.21)),
    'HandTowelHolder': (_hand_towel_holder, _wide, (0.05, 0.17, 0.21)),
    'LightSwitch': (_light_switch, _wide, (0.02, 0.12, 0.15)),
    'ShowerGlass': (_shower_glass, _wide, (0.07, 1.79, 1.97)),
    'ShowerHead': (_shower_head, _deep, (0.25, 0.12, 1.0)),
    'Sink': (_sink, _wide, (0.46, 0.67, 0.16)),
    'SinkBasin': (_sink_basin, _wide, (0.33, 0.53, 0.13)),
    'StoveBurner': (_stove_burner, _wide, (0.22, 0.22, 0.02)),
    'StoveKnob': (_stove_knob, _wide, (0.06, 0.07, 0.07)),
    'Toaster': (_toaster, _wide, (0.22, 0.36, 0.21)),
    'ToiletPaperHanger': (_toilet_paper_hanger, _wide, (0.1, 0.23, 0.08)),
    'TowelHolder': (_towel_holder, _wide, (0.11, 0.66, 0.04)),
    # lamps, plants, screens, wall decoration
    'Curtains': (_curtains, _wide, (0.14, 2.17, 2.17)),
    'DeskLamp': (_desk_lamp, _wide, (0.28, 0.29, 0.46)),
    'FloorLamp': (_floor_lamp, _wide, (0.52, 0.52, 1.88)),
    'HousePlant': (_house_plant, _wide, (0.33, 0.39, 0.64)),
    'Lamp': (_lamp, _wide, (0.35, 0.35, 0.62)),
    'Mirror': (_mirror, _wide, (0.05, 0.84, 0.85)),
    'Painting': (_painting, _wide, (0.09, 0.88, 0.84)),
    'Poster': (_poster, _wide, (0.09, 0.62, 0.71)),
    'Television': (_television, _wide, (0.32, 1.12, 0.81)),
    'Window': (_window, _wide, (0.11, 1.07, 1.55)),
}

TYPES_WITH_SHAPES: tuple[str, ...] = tuple(sorted(_TYPES))


def shape_for(type_name: str, dims: Optional[tuple[float, float, float]]) -> ShapeSpec:
    """The composed shape of `type_name`, scaled by the catalogue's approx_size_m `dims`.

    dims: the three numbers of approx_size_m as given (sorted edges for pickupables, length x
    width x height for fixed objects), or None to use the type's default extents.
    Raises KeyError for an unknown type. Specs are immutable and cached per (type, dims).
    """
    return _shape(type_name, None if dims is None else tuple(float(v) for v in dims))


@functools.lru_cache(maxsize=None)
def _shape(type_name: str, dims: Optional[tuple[float, ...]]) -> ShapeSpec:
    builder, layout, default = _TYPES[type_name]
    xyz = default if dims is None else layout(dims)
    return builder(*(max(v, _MIN_EDGE) for v in xyz))
