"""Every default lives in its Options struct: the keyword defaults of feedid.identify, gains, simulate, synth and plan
are the library's (feedid._feedid.defaults() reads them from default-constructed structs), and a call with the
defaults does what the command line does without options. A default typed into a signature and changed on one side
only fails here."""

import inspect

import feedid
from feedid import _feedid

from conftest import cli_json

# Keywords with a default that is no Options struct's: which demo drive synth starts from.
NOT_OPTIONS = {"synth": {"rotary"}}


def test_every_keyword_default_is_the_librarys():
    defaults = _feedid.defaults()
    assert sorted(defaults) == ["gains", "identify", "plan", "simulate", "synth"]
    for name, library in defaults.items():
        parameters = inspect.signature(getattr(feedid, name)).parameters
        for keyword, value in library.items():
            assert keyword in parameters, (name, keyword)
            default = parameters[keyword].default
            assert default == value and type(default) is type(value), (name, keyword, default, value)
        # and no keyword has a default of its own (None: "not given", the library decides)
        for keyword, parameter in parameters.items():
            if parameter.default is inspect.Parameter.empty or parameter.default is None:
                continue
            assert keyword in library or keyword in NOT_OPTIONS.get(name, set()), (name, keyword, parameter.default)


def test_the_defaults_are_the_structs_in_the_keywords_units():
    plan = _feedid.defaults()["plan"]
    # TestPlanOptions: a 30 mm stroke, 5000 mm/min between passes, 7 slow feeds from 10 to 1000 mm/min, ...
    assert plan["stroke_mm"] == 30.0 and plan["positioning_feed_mm_per_min"] == 5000.0
    assert plan["slow_feeds_mm_per_min"] == "10:1000:7"
    # PredictionOptions: the demo drive, which demo_drive() gives as a drive file
    drive = feedid.demo_drive()["axis"]
    assert plan["mass_kg"] == drive["mass_kg"]
    identify = _feedid.defaults()["identify"]
    assert identify["forgetting_factor"] == 0.99995 and identify["differentiation"] == "butterworth"


def test_plan_with_its_defaults_is_the_cli_without_options():
    expected = cli_json("plan", "--travel=-400:400", "--centers=-100,100")
    assert feedid.plan(travel_mm=(-400, 400), centers_mm=[-100, 100]).to_dict() == expected
