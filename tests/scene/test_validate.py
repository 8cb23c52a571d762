"""Scene value validation and its one-line errors (docs/model.md §1; wooddecay.scene.validate)."""
from __future__ import annotations

import pytest

from wooddecay.species import SPECIES

from .conftest import error, parse


@pytest.mark.parametrize("extra, key, needle", [
    ("[strands]\nr_s = -1", "strands.r_s", "-1 is outside (0, 1] m"),
    ("[strands]\nr_s = 0", "strands.r_s", "(0, 1] m"),
    ("[strands]\nr_s = 'big'", "strands.r_s", "got string 'big'"),
    ("[strands]\nr_s = true", "strands.r_s", "got boolean true"),
    ("[strands]\nr_s = [1]", "strands.r_s", "got array"),
    ("[strands]\nr_s = nan", "strands.r_s", "not a finite number"),
    ("[strands]\nr_s = inf", "strands.r_s", "not a finite number"),
    ("[weakpoints]\nk_W = 1.0", "weakpoints.k_W", "1.0 is outside [0, 1)"),
    ("[fungi]\nD_w = 1", "fungi.D_w", "outside [0, 0.01] m^2/day"),
    ("[fungi]\nalpha_w0 = -0.1", "fungi.alpha_w0", "[0, 10] 1/day"),
    ("[time]\nframes = 0", "time.frames", "0 is outside [1, 100000]"),
    ("[time]\nframes = 2.5", "time.frames", "expected an integer in [1, 100000]"),
    ("[time]\nframes = true", "time.frames", "got boolean"),
    ("[scene]\nseed = -1", "scene.seed", "-1 is outside [0, inf)"),
    ("[scene]\nquality = 'best'", "scene.quality", "one of 'draft', 'final'"),
    ("[scene]\nname = 3", "scene.name", "expected a string"),
    ("[export]\nusd = 1", "export.usd", "expected true or false"),
    ("[export]\ngltf_frame = 1.5", "export.gltf_frame", "expected an integer"),
    ("[mechanics]\ngravity = [0, 0]", "mechanics.gravity", "3 finite numbers"),
    ("[mechanics]\ngravity = [0, 0, nan]", "mechanics.gravity", "not finite"),
    ("[mechanics]\ngravity = [0, 0, true]", "mechanics.gravity", "boolean"),
    ("[mechanics]\nE = 0", "mechanics.E", "0 is outside (0, 1e13] Pa"),
    ("[moisture]\nschedule = [[0, 1.0, 0.1], [0, 1.0, 0.1]]", "moisture.schedule[1]", "strictly increasing"),
    ("[moisture]\nschedule = [[-1, 1.0, 0.1]]", "moisture.schedule[0]", "[0, inf) day"),
    ("[moisture]\nschedule = [[5, 0.1, 0.5]]", "moisture.schedule[0]", "M_2 0.5 must be < M_1 0.1"),
    ("[moisture]\nschedule = [[5, 0.1]]", "moisture.schedule[0]", "[day, M_1, M_2]"),
    ("[moisture]\nschedule = 3", "moisture.schedule", "got integer 3"),
    ("strands = 3", "strands", "expected a table [strands]"),
])
def test_value_errors(extra, key, needle):
    err = error(extra)
    assert err.file == "samples/log.toml"
    assert err.key == key
    assert needle in err.message, str(err)
    assert str(err).startswith(f"samples/log.toml: {key}: ")


def test_error_message_exact():
    assert str(error("[strands]\nr_s = -1")) == "samples/log.toml: strands.r_s: -1 is outside (0, 1] m"


def test_did_you_mean():
    err = error("[fungi]\nalpah_w0 = 1e-3")
    assert err.key == "fungi.alpah_w0"
    assert err.message == "unknown key 'alpah_w0' in [fungi]; did you mean 'alpha_w0'?"
    err = error("[fungii]\nalpha_w0 = 1e-3")
    assert err.key == "fungii" and "did you mean 'fungi'?" in err.message
    err = error("[fungi]\nM_1 = 1.0")
    assert "belongs in [moisture]" in err.message
    err = error("r_s = 1.0")
    assert err.key == "r_s" and "belongs in [strands]" in err.message
    err = error("[tissue.heartwod]\nalpha_w0 = 0.01")
    assert err.key == "tissue.heartwod" and "did you mean 'heartwood'?" in err.message
    err = error("[tissue.heartwood]\nalpha_w = 0.01")
    assert err.key == "tissue.heartwood.alpha_w" and "did you mean 'alpha_w0'?" in err.message
    err = error("[tissue.heartwood]\nr_s = 0.01")
    assert err.key == "tissue.heartwood.r_s"
    err = error("[scene]\nquality = 'drafts'")
    assert "did you mean 'draft'?" in err.message


def test_tissue_override_validated_against_range():
    err = error("[tissue.pith]\nk_W = 0.5")  # not a tissue section key
    assert err.key == "tissue.pith.k_W"
    err = error("[tissue.sapwood]\nalpha_w0 = 11")
    assert err.key == "tissue.sapwood.alpha_w0" and "outside [0, 10] 1/day" in err.message
    err = error("[tissue.sapwood]\nmu_f = 'x'")
    assert err.key == "tissue.sapwood.mu_f" and "[0, 2]" in err.message
    err = error("tissue = 1")
    assert err.key == "tissue"
    err = error("[tissue]\nbark = 1")
    assert err.key == "tissue.bark"


def test_consistency_errors():
    err = error("[moisture]\nM_2 = 1.0")
    assert err.key == "moisture.M_2" and "moisture.M_1" in err.message and "< M_1" in err.message
    err = error("[moisture]\nM_1 = 0.5\nM_2 = 0.6")
    assert err.key == "moisture.M_2"
    err = error("[moisture]\nM_init = 2.0")
    assert err.key == "moisture.M_init" and "[M_2, M_1]" in err.message
    err = error("[fungi]\nM_min = 0.9\nM_max = 0.2")
    assert err.key == "fungi.M_min" and "fungi.M_max" in err.message
    err = error("[strands]\nconnect_radius = 0.011")
    assert err.key == "strands.connect_radius" and "strands.r_s" in err.message
    err = error("[strands]\nr_s = 0.01\nconnect_radius = 0.015")
    assert err.key == "strands.connect_radius"
    assert parse("[strands]\nconnect_radius = 0.012").strands.connect_radius == 0.012
    err = error("[tissue.heartwood]\nM_2 = 1.5")
    assert err.key == "tissue.heartwood.M_2" and "tissue.heartwood.M_1" in err.message
    err = error("[tissue.bark]\nM_max = 0.1")
    assert err.key == "tissue.bark.M_max"


@pytest.mark.parametrize("region, key, needle", [
    ("{kind = 'cube'}", "inoculation[0].region.kind", "one of 'box', 'sphere', 'node', 'end', 'wound'"),
    ("{min = [0, 0, 0]}", "inoculation[0].region.kind", "missing required key 'kind'"),
    ("{kind = 'box', min = [0, 0, 0], max = [1, 0, 1]}", "inoculation[0].region.max", "every component"),
    ("{kind = 'box', min = [0, 0, 0]}", "inoculation[0].region.max", "missing required key"),
    ("{kind = 'sphere', center = [0, 0, 0], radius = 0}", "inoculation[0].region.radius", "(0, inf) m"),
    ("{kind = 'sphere', centre = [0, 0, 0], radius = 1}", "inoculation[0].region.centre", "did you mean 'center'?"),
    ("{kind = 'node', id = 'tpi', radius = 0.1}", "inoculation[0].region.id", "did you mean 'tip'?"),
    ("{kind = 'node', id = true, radius = 0.1}", "inoculation[0].region.id", "node id"),
    ("{kind = 'end', which = 'top', depth = 0.1}", "inoculation[0].region.which", "'root', 'tip'"),
    ("{kind = 'end', depth = -0.1}", "inoculation[0].region.depth", "(0, inf) m"),
    ("{kind = 'wound', position = [0, 0], radius = 1, depth = 1}", "inoculation[0].region.position", "3 finite"),
    ("{kind = 'sphere', center = [0, 0, 0], radius = 1, space = 'local'}", "inoculation[0].region.space",
     "'world', 'wood'"),
    ("3", "inoculation[0].region", "expected a region table"),
])
def test_region_errors(region, key, needle):
    err = error(f"[[inoculation]]\nfungus = 'white'\nregion = {region}")
    assert err.key == key and needle in err.message, str(err)


@pytest.mark.parametrize("body, key, needle", [
    ("region = {kind = 'end', depth = 0.1}", "inoculation[0].fungus", "missing required key 'fungus'"),
    ("fungus = 'white'", "inoculation[0].region", "missing required key 'region'"),
    ("fungus = 'grey'\nregion = {kind = 'end', depth = 0.1}", "inoculation[0].fungus", "one of 'white', 'brown'"),
    ("fungus = 'white'\nactivity = 0\nregion = {kind = 'end', depth = 0.1}", "inoculation[0].activity", "(0, 1]"),
    ("fungus = 'white'\nday = -1\nregion = {kind = 'end', depth = 0.1}", "inoculation[0].day", "[0, inf) day"),
    ("fungus = 'white'\nstrength = 1\nregion = {kind = 'end', depth = 0.1}", "inoculation[0].strength",
     "unknown key"),
])
def test_inoculation_errors(body, key, needle):
    err = error(f"[[inoculation]]\n{body}")
    assert err.key == key and needle in err.message, str(err)


def test_inoculation_not_array():
    assert error("inoculation = 3").key == "inoculation"
    assert error("[inoculation]\nfungus = 'white'").key == "inoculation"


@pytest.mark.parametrize("body, key, needle", [
    ("force = [0, 0, 1]\ndays = [0, 1]", "load[0].region", "missing required key"),
    ("region = {kind = 'end', depth = 0.1}\nforce = [0, 1]\ndays = [0, 1]", "load[0].force", "3 finite"),
    ("region = {kind = 'end', depth = 0.1}\nforce = [0, 0, 1]\ndays = [2, 1]", "load[0].days", "start"),
    ("region = {kind = 'end', depth = 0.1}\nforce = [0, 0, 1]\ndays = [-1, 1]", "load[0].days", "[0, inf) day"),
    ("region = {kind = 'end', depth = 0.1}\nforce = [0, 0, 1]\ndays = 3", "load[0].days", "[start, end]"),
    ("region = {kind = 'end', depth = 0.1}\nforce = [0, 0, 1]", "load[0].days", "missing required key"),
])
def test_load_errors(body, key, needle):
    err = error(f"[[load]]\n{body}")
    assert err.key == key and needle in err.message, str(err)


def test_connection_shear_needs_the_implicit_solver():
    err = error("[mechanics]\nconnection_shear = 0.5")
    assert err.key == "mechanics.connection_shear" and "mechanics.solver = 'implicit'" in err.message
    assert parse("[mechanics]\nsolver = 'implicit'\nconnection_shear = 0.5").mechanics.connection_shear == 0.5


def test_a_species_needs_the_implicit_solver_and_sets_the_moduli():
    err = error("[wood]\nspecies = 'oak'")
    assert err.key == "wood.species" and "mechanics.solver = 'implicit'" in err.message, str(err)
    for key in ("E = 2e9", "G = 1e9", "rho_dry = 500.0", "connection_shear = 0.5"):
        err = error(f"[wood]\nspecies = 'oak'\n[mechanics]\nsolver = 'implicit'\n{key}")
        assert err.key == f"mechanics.{key.split()[0]}" and "wood.species = 'oak'" in err.message, str(err)
    scene = parse("[wood]\nspecies = 'spruce'\n[mechanics]\nsolver = 'implicit'")
    rods = SPECIES["spruce"].rod_moduli()
    assert (scene.mechanics.E, scene.mechanics.G, scene.mechanics.rho_dry) == (rods.E, rods.G, 400.0)
    err = error("[mechanics]\nsolver = 'implicit'\n[tissue.heartwood]\nspecies = 'oak'")
    assert err.key == "tissue.heartwood.species" and "[wood] species" in err.message, str(err)
    paper = parse("[mechanics]\nsolver = 'implicit'")
    assert (paper.wood.species, paper.mechanics.E, paper.mechanics.G) == ("none", 1e9, 4e8)
