"""Bond-graph engine: causality (SCAP), state-space matrices, power balance and structural errors.

Every expected value below is derived by hand from the bond-graph rules, not read off the engine.
"""

import numpy as np
import pytest
from power_balance import power_residuals  # tests/power_balance.py

from ea_gym import models
from ea_gym.bondgraph.causality import assign_causality
from ea_gym.bondgraph.elements import Kind
from ea_gym.bondgraph.equations import StateSpaceModel
from ea_gym.bondgraph.graph import BondGraph, BondGraphError

# --------------------------------------------------------------------------------------------------
# helpers


def bond_index(graph: BondGraph, tail: str, head: str) -> int:
    return graph.bonds.index(next(b for b in graph.bonds if (b.tail, b.head) == (tail, head)))


def tf_graph() -> BondGraph:
    """Se U -> 1a (Ra) -> TF n -> 1b (I, R): a voltage source driving, through a gear, a damped inertia."""
    g = BondGraph()
    g.add("U", "Se").add("a", "1").add("Ra", "R").add("n", "TF").add("b", "1").add("J", "I").add("R", "R")
    g.connect("U", "a").connect("a", "Ra").connect("a", "n").connect("n", "b").connect("b", "J").connect("b", "R")
    return g


def loop_graph() -> BondGraph:
    """A resistor network with an algebraic loop.

    Se U -> 1a: R1 in series with the 0-junction b; at b: R2 in parallel with the 1-junction c,
    which holds R3 in series with the capacitor C. No storage or source decides the causality of
    R1, R2 or R3, so the SCAP has to pick one arbitrarily (an algebraic loop through R1-R2-R3).
    """
    g = BondGraph()
    g.add("U", "Se").add("a", "1").add("R1", "R").add("b", "0").add("R2", "R").add("c", "1")
    g.add("R3", "R").add("C", "C")
    g.connect("U", "a").connect("a", "R1").connect("a", "b").connect("b", "R2").connect("b", "c")
    g.connect("c", "R3").connect("c", "C")
    return g


# --------------------------------------------------------------------------------------------------
# causality


def test_causality_of_spring_mass_damper():
    # Se F imposes the effort on its bond, so its input (what the graph gives back) is the flow.
    # At the 1-junction v the integral-causality I element m takes the effort (dp/dt = e) and fixes
    # the common flow v = p/m; the spring k and the damper b then receive that flow (C integral: e = k q;
    # R: e = b f).
    ss = models.spring_mass_damper().state_space
    c = ss.causality
    assert c.inputs == {"F": "flow", "m": "effort", "k": "flow", "b": "flow"}
    # bonds in order v->m, v->k, v->b, F->v: the junction sets m's effort, k and b set their own,
    # F sets the effort of its bond.
    assert c.effort_setter == ("v", "k", "b", "F")
    assert c.algebraic_loop == ()
    assert c.is_integral("m", Kind.I) and c.is_integral("k", Kind.C)


def test_causality_of_rlc_circuit():
    # 1-junction i (common current): L1 in integral causality receives the voltage and fixes i;
    # R1 receives i (flow). 0-junction u_c (common voltage): C1 in integral causality receives the
    # current and fixes u_c = q/C; R2 receives u_c (effort) and the bond i->u_c takes its effort from u_c.
    ss = models.rlc_circuit().state_space
    c = ss.causality
    assert c.inputs == {"U": "flow", "R1": "flow", "L1": "effort", "C1": "flow", "R2": "effort"}
    # bonds: U->i, i->R1, i->L1, i->u_c, u_c->C1, u_c->R2
    assert c.effort_setter == ("U", "R1", "i", "u_c", "C1", "u_c")
    assert c.algebraic_loop == ()
    assert c.is_integral("L1", Kind.I) and c.is_integral("C1", Kind.C)


def test_causality_of_dc_motor():
    # 1-junction i: La (integral) fixes the current; Ra and the GY receive it. A GY turns a flow
    # into an effort on both sides: it sets the back-EMF on i->K and the torque on K->w. 1-junction w:
    # J (integral) receives the net torque and fixes w; bm receives w.
    ss = models.dc_motor().state_space
    c = ss.causality
    assert c.inputs == {"V": "flow", "Ra": "flow", "La": "effort", "J": "effort", "bm": "flow"}
    # bonds: V->i, i->Ra, i->La, i->K, K->w, w->J, w->bm
    assert c.effort_setter == ("V", "Ra", "i", "K", "K", "w", "bm")
    assert c.algebraic_loop == ()
    assert c.is_integral("La", Kind.I) and c.is_integral("J", Kind.I)


@pytest.mark.parametrize("factory", [models.spring_mass_damper, models.rlc_circuit, models.dc_motor])
def test_every_storage_element_of_the_built_in_models_is_integral(factory):
    model = factory()
    c = model.state_space.causality
    storage = model.graph.names([Kind.I, Kind.C])
    assert storage and list(model.state_names) == storage
    for name in storage:
        assert c.is_integral(name, model.graph.elements[name].kind)


def test_is_integral_distinguishes_i_and_c():
    c = models.spring_mass_damper().state_space.causality
    # m receives an effort: integral for an I, it would be derivative for a C
    assert c.is_integral("m", Kind.I) and not c.is_integral("m", Kind.C)
    assert c.is_integral("k", Kind.C) and not c.is_integral("k", Kind.I)


# --------------------------------------------------------------------------------------------------
# state-space matrices against hand-derived ones


def test_spring_mass_damper_matrices_batched():
    # m dv/dt = F - k x - b v with p = m v, q = x:
    #   dp/dt = F - k q - (b/m) p,  dq/dt = p/m
    ss = models.spring_mass_damper().state_space
    assert ss.parameter_names == ("m", "k", "b")
    assert ss.state_names == ("m", "k")
    theta = np.array([[10.0, 100.0, 0.5], [2.0, 7.0, 3.0], [0.5, 1e3, 1e-3]])
    mats = ss.matrices(theta)
    assert mats.A.shape == (3, 2, 2) and mats.B.shape == (3, 2, 1)
    assert mats.Cy.shape == (3, 8, 2) and mats.Dy.shape == (3, 8, 1)
    for j, (m, k, b) in enumerate(theta):
        A = np.array([[-b / m, -k], [1.0 / m, 0.0]])
        np.testing.assert_allclose(mats.A[j], A, rtol=1e-14, atol=0)
        np.testing.assert_allclose(mats.B[j], [[1.0], [0.0]], rtol=0, atol=1e-15)
    # a single parameter set gives unbatched matrices equal to the batched ones
    single = ss.matrices(theta[1])
    assert single.A.shape == (2, 2)
    np.testing.assert_allclose(single.A, mats.A[1], rtol=1e-15, atol=0)


def test_rlc_circuit_matrices():
    # p = L1 i (flux), q = C1 u_c (charge):
    #   L1 di/dt = U - R1 i - u_c        ->  dp/dt = U - (R1/L1) p - q/C1
    #   C1 du_c/dt = i - u_c / R2        ->  dq/dt = p/L1 - q/(R2 C1)
    ss = models.rlc_circuit().state_space
    assert ss.parameter_names == ("R1", "L1", "C1", "R2") and ss.state_names == ("L1", "C1")
    theta = np.array([[2.0, 1.0, 0.01, 50.0], [0.3, 0.2, 3.0, 7.0]])
    mats = ss.matrices(theta)
    for j, (R1, L1, C1, R2) in enumerate(theta):
        A = np.array([[-R1 / L1, -1.0 / C1], [1.0 / L1, -1.0 / (R2 * C1)]])
        np.testing.assert_allclose(mats.A[j], A, rtol=1e-13, atol=0)
        np.testing.assert_allclose(mats.B[j], [[1.0], [0.0]], rtol=0, atol=1e-15)


def test_dc_motor_matrices():
    # p_a = La i, p_J = J w; the gyrator gives back-EMF K w and torque K i:
    #   La di/dt = V - Ra i - K w   ->  dp_a/dt = V - (Ra/La) p_a - (K/J) p_J
    #   J dw/dt = K i - bm w        ->  dp_J/dt = (K/La) p_a - (bm/J) p_J
    ss = models.dc_motor().state_space
    assert ss.parameter_names == ("K", "Ra", "La", "J", "bm") and ss.state_names == ("La", "J")
    theta = np.array([[0.1, 1.0, 0.05, 0.01, 0.001], [2.0, 0.5, 3.0, 0.7, 0.2]])
    mats = ss.matrices(theta)
    for j, (K, Ra, La, J, bm) in enumerate(theta):
        A = np.array([[-Ra / La, -K / J], [K / La, -bm / J]])
        np.testing.assert_allclose(mats.A[j], A, rtol=1e-13, atol=0)
        np.testing.assert_allclose(mats.B[j], [[1.0], [0.0]], rtol=0, atol=1e-15)


def test_transformer_matrices():
    # TF modulus n: e_in = n e_out, f_out = n f_in. With p = J w (w the flow out of the TF):
    #   U = Ra f_in + e_in = Ra w / n + n e_out,  J dw/dt = e_out - R w
    #   -> dp/dt = U/n - (Ra/n^2 + R) p / J
    ss = StateSpaceModel(tf_graph())
    assert ss.parameter_names == ("Ra", "n", "J", "R")
    theta = np.array([[1.0, 3.0, 2.0, 0.5], [0.2, 0.5, 0.1, 4.0]])
    mats = ss.matrices(theta)
    for j, (Ra, n, J, R) in enumerate(theta):
        np.testing.assert_allclose(mats.A[j], [[-(Ra / n**2 + R) / J]], rtol=1e-14, atol=0)
        np.testing.assert_allclose(mats.B[j], [[1.0 / n]], rtol=1e-14, atol=0)
    # the output map: bond a->n carries e_in = U - Ra w/n and f_in = w/n; bond n->b e_out = e_in/n, f_out = w
    Ra, n, J, R = theta[0]
    x, U = np.array([0.7]), np.array([2.5])
    z = mats.Cy[0] @ x + mats.Dy[0] @ U
    g = ss.graph
    nb = len(g.bonds)
    i_in, i_out = bond_index(g, "a", "n"), bond_index(g, "n", "b")
    w = x[0] / J
    np.testing.assert_allclose(z[nb + i_out], w, rtol=1e-14)
    np.testing.assert_allclose(z[nb + i_in], w / n, rtol=1e-14)
    np.testing.assert_allclose(z[i_in], U[0] - Ra * w / n, rtol=1e-14)
    np.testing.assert_allclose(z[i_out], (U[0] - Ra * w / n) / n, rtol=1e-14)


def test_matrices_reject_a_wrong_parameter_length():
    ss = models.spring_mass_damper().state_space
    with pytest.raises(ValueError, match="last axis of length 3"):
        ss.matrices(np.ones(4))


# --------------------------------------------------------------------------------------------------
# power balance from the output maps


@pytest.mark.parametrize(
    "graph_factory",
    [
        lambda: models.spring_mass_damper().graph,
        lambda: models.rlc_circuit().graph,
        lambda: models.dc_motor().graph,
        tf_graph,
        loop_graph,
    ],
    ids=["spring_mass_damper", "rlc_circuit", "dc_motor", "transformer", "algebraic_loop"],
)
def test_power_is_conserved_at_junctions_and_two_ports(graph_factory):
    graph = graph_factory()
    ss = StateSpaceModel(graph)
    rng = np.random.default_rng(42)
    theta = rng.uniform(0.2, 5.0, size=(4, len(ss.parameter_names)))
    mats = ss.matrices(theta)
    x = rng.normal(size=(4, 50, ss.n_states))
    u = rng.normal(size=(4, 50, ss.n_inputs))
    z = np.einsum("bij,bkj->bki", mats.Cy, x) + np.einsum("bij,bkj->bki", mats.Dy, u)
    residuals = power_residuals(graph, z)
    assert residuals  # every graph here has at least one junction
    for name, (net, scale) in residuals.items():
        assert np.all(scale > 0), name
        assert np.all(np.abs(net) <= 1e-12 * scale), (name, np.abs(net / scale).max())
    # and the check itself is sharp: a perturbed flow breaks the balance
    z_bad = z.copy()
    z_bad[..., len(graph.bonds)] *= 1.01
    assert any(np.any(np.abs(net) > 1e-6 * scale) for net, scale in power_residuals(graph, z_bad).values())


def test_two_port_power_in_equals_power_out():
    graph = tf_graph()
    ss = StateSpaceModel(graph)
    rng = np.random.default_rng(1)
    theta = rng.uniform(0.2, 5.0, size=(6, 4))
    mats = ss.matrices(theta)
    x, u = rng.normal(size=(6, 1)), rng.normal(size=(6, 1))
    z = (mats.Cy @ x[..., None])[..., 0] + (mats.Dy @ u[..., None])[..., 0]
    nb = len(graph.bonds)
    i_in, i_out = graph.two_port_bonds("n")
    p_in, p_out = z[:, i_in] * z[:, nb + i_in], z[:, i_out] * z[:, nb + i_out]
    np.testing.assert_allclose(p_in, p_out, rtol=1e-12, atol=0)
    assert np.all(np.abs(p_in) > 0)


# --------------------------------------------------------------------------------------------------
# algebraic loop


def test_algebraic_loop_is_solved_as_a_resistor_network():
    graph = loop_graph()
    ss = StateSpaceModel(graph)
    assert ss.causality.algebraic_loop, "the R1-R2-R3 network needs an arbitrary causality choice"
    assert set(ss.causality.algebraic_loop) <= {"R1", "R2", "R3"}
    assert ss.parameter_names == ("R1", "R2", "R3", "C") and ss.state_names == ("C",)

    rng = np.random.default_rng(7)
    theta = rng.uniform(0.5, 5.0, size=(5, 4))
    mats = ss.matrices(theta)
    q = rng.normal(size=5)
    U = rng.normal(size=5)
    z = mats.Cy[:, :, 0] * q[:, None] + mats.Dy[:, :, 0] * U[:, None]
    nb = len(graph.bonds)
    for j, (R1, R2, R3, C) in enumerate(theta):
        # nodal analysis at b (voltage v_b), with capacitor voltage v_c = q / C:
        #   (U - v_b)/R1 = v_b/R2 + (v_b - v_c)/R3
        v_c = q[j] / C
        v_b = (U[j] / R1 + v_c / R3) / (1 / R1 + 1 / R2 + 1 / R3)
        i1, i2, i3 = (U[j] - v_b) / R1, v_b / R2, (v_b - v_c) / R3
        expected = {
            ("U", "a"): (U[j], i1),
            ("a", "R1"): (R1 * i1, i1),
            ("a", "b"): (v_b, i1),
            ("b", "R2"): (v_b, i2),
            ("b", "c"): (v_b, i3),
            ("c", "R3"): (R3 * i3, i3),
            ("c", "C"): (v_c, i3),
        }
        for (tail, head), (effort, flow) in expected.items():
            i = bond_index(graph, tail, head)
            np.testing.assert_allclose(z[j, i], effort, rtol=1e-12, atol=1e-14, err_msg=f"e {tail}->{head}")
            np.testing.assert_allclose(z[j, nb + i], flow, rtol=1e-12, atol=1e-14, err_msg=f"f {tail}->{head}")
        # dq/dt = i3 = d + e q + g U: A = (1/(R3 C)) (r - 1), B = r / (R1 R3 s) with s = sum of conductances
        s = 1 / R1 + 1 / R2 + 1 / R3
        np.testing.assert_allclose(mats.A[j, 0, 0], (1 / (R3 * s * R3) - 1 / R3) / C, rtol=1e-12)
        np.testing.assert_allclose(mats.B[j, 0, 0], 1 / (R1 * s * R3), rtol=1e-12)
        # steady state: no current through C, so v_c is the R1-R2 divider of U
        q_ss = -mats.B[j, 0, 0] * U[j] / mats.A[j, 0, 0]
        np.testing.assert_allclose(q_ss / C, U[j] * R2 / (R1 + R2), rtol=1e-12)


# --------------------------------------------------------------------------------------------------
# malformed graphs


def _se_one(g: BondGraph) -> BondGraph:
    return g.add("F", "Se").add("j", "1").connect("F", "j")


def test_derivative_causality_of_two_masses_on_one_junction_names_the_element():
    g = _se_one(BondGraph())
    g.add("m1", "I").add("m2", "I").add("b", "R")
    g.connect("j", "m1").connect("j", "m2").connect("j", "b")
    with pytest.raises(BondGraphError, match=r"derivative causality") as info:
        assign_causality(g)
    assert "'m2'" in str(info.value) and "'m1'" not in str(info.value)
    with pytest.raises(BondGraphError, match=r"\['m2'\].*derivative"):
        StateSpaceModel(g)


def test_derivative_causality_of_a_capacitor_on_an_effort_source():
    g = BondGraph().add("U", "Se").add("node", "0").add("cap", "C").add("r", "R")
    g.connect("U", "node").connect("node", "cap").connect("node", "r")
    with pytest.raises(BondGraphError, match=r"\['cap'\] are in derivative causality"):
        assign_causality(g)


def test_two_effort_sources_on_one_zero_junction_conflict_names_the_junction():
    g = BondGraph().add("S1", "Se").add("S2", "Se").add("node", "0").add("r", "R")
    g.connect("S1", "node").connect("S2", "node").connect("node", "r")
    with pytest.raises(BondGraphError, match=r"causal conflict.*node"):
        assign_causality(g)


def test_two_flow_sources_on_one_one_junction_conflict_names_the_junction():
    g = BondGraph().add("Q1", "Sf").add("Q2", "Sf").add("belt", "1").add("r", "R")
    g.connect("Q1", "belt").connect("Q2", "belt").connect("belt", "r")
    with pytest.raises(BondGraphError, match=r"causal conflict.*belt"):
        assign_causality(g)


def test_one_port_with_two_bonds():
    g = BondGraph().add("F", "Se").add("j", "1").add("k", "0").add("damper", "R")
    g.connect("F", "j").connect("j", "damper").connect("damper", "k").connect("j", "k")
    with pytest.raises(BondGraphError, match=r"R element 'damper' needs exactly 1 bond, has 2"):
        g.validate()
    with pytest.raises(BondGraphError, match=r"'damper'"):
        StateSpaceModel(g)


def test_transformer_needs_one_bond_in_and_one_out():
    g = BondGraph().add("F", "Se").add("j", "1").add("gear", "TF").add("j2", "1").add("m", "I")
    # both bonds point into the TF
    g.connect("F", "j").connect("j", "gear").connect("j2", "gear").connect("j2", "m")
    with pytest.raises(BondGraphError, match=r"TF element 'gear' needs exactly one bond in and one bond out, has 2 in and 0 out"):
        assign_causality(g)


def test_unknown_kind():
    with pytest.raises(BondGraphError, match=r"element 'x': unknown kind 'Q'"):
        BondGraph().add("x", "Q")


def test_duplicate_name():
    g = BondGraph().add("m", "I")
    with pytest.raises(BondGraphError, match=r"element 'm' is defined twice"):
        g.add("m", "R")


def test_bond_to_an_unknown_element():
    g = BondGraph().add("F", "Se")
    with pytest.raises(BondGraphError, match=r"no element named 'ghost'"):
        g.connect("F", "ghost")
    with pytest.raises(BondGraphError, match=r"no element named 'ghost'"):
        g.connect("ghost", "F")


def test_bond_joining_two_one_ports_directly():
    g = BondGraph().add("F", "Se").add("b", "R").connect("F", "b")
    with pytest.raises(BondGraphError, match=r"\(F->b\) joins two one-port elements"):
        assign_causality(g)


def test_empty_graph_and_dangling_junction():
    with pytest.raises(BondGraphError, match="no elements"):
        BondGraph().validate()
    g = _se_one(BondGraph())
    with pytest.raises(BondGraphError, match=r"junction 'j' needs at least 2 bonds, has 1"):
        g.validate()


def test_junction_that_nothing_drives_is_rejected_by_name():
    # Sf sets the flow into 0-junction "a"; its only other bonds go to 1-junction "b", whose flow is set
    # by the I element, so nothing imposes the effort of "a": the model is under-determined.
    g = BondGraph().add("Q", "Sf").add("a", "0").add("b", "1").add("m", "I")
    g.connect("Q", "a").connect("a", "b").connect("b", "a").connect("b", "m")
    with pytest.raises(BondGraphError, match=r"0-junction 'a' has no bond that imposes its effort"):
        assign_causality(g)


@pytest.mark.parametrize("name", ["spring_mass_damper", "rlc_circuit", "dc_motor"])
def test_the_state_equation_is_the_state_derivative_map_times_each_output_map_to_the_bit(name):
    """A and B come out of one product of S with [Cy | Dy]: the same bits as S @ Cy and S @ Dy apart."""
    model = models.get_model(name)
    ss = model.state_space
    mats = ss.matrices(model.parameter_vector() * np.random.default_rng(3).uniform(0.5, 2.0, (6, len(ss.parameter_names))))
    assert mats.A.tobytes() == (ss._S @ mats.Cy).tobytes() and mats.B.tobytes() == (ss._S @ mats.Dy).tobytes()
