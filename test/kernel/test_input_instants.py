"""Inputs at their own instants: split steps, the offline replay of kHz inputs, the reference."""
from input_cases import khz_case, MASSES, mixed_consist, replay
import numpy as np

from train_dynamics import topics
from train_dynamics.physics.chain_reference import ChainLaw, solve_chain
from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.kernel import couplers
from train_dynamics.physics.reference import reference_solution
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.simulation.runner import CommandEvent, InputSchedule, run_simulation, step_of


def _square_events(cfg, period_ms, t_end):
    """Cylinder inputs of every coach alternating full / zero every ``period_ms`` ms."""
    pmax = cfg.max_cylinder_pressure
    events = []
    for j in range(int(round(t_end * 1000 / period_ms))):
        t_ns = j * period_ms * 1_000_000
        gauge = pmax if j % 2 == 0 else 0.0
        for i in range(cfg.consist.n):
            events.append(CommandEvent(topics.CYLINDER_PER_COACH, i, gauge, t_ns,
                                       step_of(t_ns, cfg.integration_step),
                                       topics.input_topic(topics.CYLINDER_PER_COACH, i + 1)))
    return events


def test_square_input_at_1khz_replayed_offline_reaches_the_model_at_1khz():
    """
    A cylinder input alternating full/zero every 1 ms, replayed offline at the 2 ms step.

    The braking force the model applied changes at every input (1 kHz: the force seen at each
    input instant alternates), and the train decelerates at half of full braking (mu g / 2),
    not 0 (the samples on the 2 ms ticks all zero) nor full.
    """
    cfg = SimConfig.from_dict({'num_coaches': 3, 'brake_input': 'cylinder_per_coach'})
    assert cfg.integration_step == 2e-3
    t_end = 1.0
    sims, seen = [], []

    def on_sample(sample):
        if not sims:
            sims.append(sample.sim)

    def on_input(event):
        if sims and event.index == 0 and event.t_ns > 0:
            seen.append(sims[0].brake_force[0])

    sim = run_simulation(cfg, t_end, InputSchedule(topics.CYLINDER_PER_COACH,
                                                   _square_events(cfg, 1, t_end)),
                         on_sample=on_sample, on_input=on_input)
    assert sim.fault is None
    full = cfg.adhesion_coefficient * cfg.coach_mass * cfg.gravity
    seen = np.array(seen)
    assert seen.size >= 990
    # the force over each 1 ms before an input: full before the releases (odd ms), 0 before
    # the applications (even ms)
    assert np.allclose(seen[0::2], full, rtol=1e-9) and np.allclose(seen[1::2], 0.0, atol=1e-6)
    decel = (cfg.initial_speed - sim.v.mean()) / t_end
    assert abs(decel - 0.5 * cfg.adhesion_coefficient * cfg.gravity) < 0.01


def test_error_control_converges_on_khz_replayed_cylinders():
    """
    Cylinder edges at 1 kHz (half between the 2 ms ticks): tighter tolerance, smaller error.

    Every coupler-force sample against the independent reference fed the same staircase:
    within 2 % of its peak at tolerance 1e-3, and the error never grows as the tolerance
    falls (1e-3, 1e-4, 1e-5).
    """
    times, levels, t_eval, ref = khz_case()
    peak = np.abs(ref.F).max()
    errors = []
    for tol in (1e-3, 1e-4, 1e-5):
        F, sim = replay(times, levels, t_eval, integration_tolerance=tol,
                        integration_max_steps=20000)
        assert sim.integration_stats['fallback_periods'] == 0
        errors.append(np.abs(F - ref.F).max() / peak)
    assert errors[0] < 0.02, errors
    assert errors[0] >= errors[1] >= errors[2] * 0.999, errors
    assert errors[2] < 1e-3, errors


def test_chain_reference_matches_the_tight_solution_of_the_paper_law():
    """Without free play the independent reference agrees with Radau on the kernel's law."""
    cfg = SimConfig.from_dict({'masses': MASSES, 'scale_factor': 700.0})
    sim = TrainSimulator(cfg)
    law = ChainLaw.of_simulator(sim)
    full = cfg.adhesion_coefficient * np.array(MASSES) * cfg.gravity
    lv = np.array([1.0, 0.0, 0.6, 0.3]) * full
    t_eval = np.round(np.arange(1, 401) * 0.005, 10)
    ref = solve_chain(sim.inertia, law, cfg.initial_speed, (np.array([0.5]), [lv]), t_eval)
    old = reference_solution(MASSES, law.ke, law.kf, law.kec, law.kfc, 700.0,
                             cfg.initial_speed, lambda t: lv * (t >= 0.5), 2.0, t_eval=t_eval)
    x, v = old.y[:4], old.y[4:]
    Fo = np.array([couplers.coupler_force(x[:-1, i] - x[1:, i], v[:-1, i] - v[1:, i], law.ke,
                                          law.kf, law.kec, law.kfc, couplers.TANH, 700.0)
                   for i in range(t_eval.size)])
    assert np.abs(ref.F - Fo).max() < 1e-4 * np.abs(Fo).max()
    assert ref.segments >= 2          # restarted at the input instant


def test_chain_reference_locates_free_play_and_blocking():
    """Free play and blocking: the reference stops at the law's breakpoints, forces agree."""
    cfg = SimConfig.from_dict({'masses': MASSES, 'scale_factor': 700.0, 'draw_gear_slack': 0.01,
                               'buffer_slack': 0.01, 'buffer_stroke': 0.02,
                               'draw_gear_stroke': 0.02})
    sim = TrainSimulator(cfg)
    law = ChainLaw.of_simulator(sim)
    full = cfg.adhesion_coefficient * np.array(MASSES) * cfg.gravity
    t_eval = np.round(np.arange(1, 301) * 0.005, 10)
    ref = solve_chain(sim.inertia, law, cfg.initial_speed,
                      (np.array([0.1]), [full * np.array([1.0, 0.0, 0.0, 0.0])]), t_eval)
    assert ref.segments > 4                         # free play left, blocking reached
    assert np.min(ref.y) < -(0.01 + 0.02)           # a buffer blocked
    F = couplers.coupler_force_travel(
        ref.y[-1], ref.v[-1, :-1] - ref.v[-1, 1:], law.ke, law.kf, law.kec, law.kfc, law.gt,
        law.gc, law.st, law.sc, law.kb, couplers.TANH, 700.0, sim.cpl)
    assert np.allclose(F, ref.F[-1], rtol=1e-12, atol=1e-6)


def test_free_play_impacts_resolved_under_error_control_at_a_bounded_cost():
    """
    Run-in through free play to blocking: impacts resolved, error falls with the tolerance.

    Against the independent reference, every 10 ms: at tolerance 1e-3 with the default work
    budget every force sample within 2 % and the peak within 1 %, displacements within 2 %;
    1e-4 no worse (the impacts' periods run out of the budget and finish in equal steps,
    not at the fixed step); at most twice the budget of steps per output period.
    """
    t_eval = np.round(np.arange(1, 251) * 0.01, 10)
    sim, steps = mixed_consist()
    ref = solve_chain(sim.inertia, ChainLaw.of_simulator(sim), 20.0, steps, t_eval)
    assert ref.segments > 10 and np.min(ref.y) < -0.03          # blocked buffers
    peak = np.abs(ref.F).max()
    errors = []
    for tol in (1e-3, 1e-4):
        sim, _ = mixed_consist(integration_tolerance=tol)
        F, Y = [], []
        for t in t_eval:
            sim.advance_to(t)
            F.append(sim.coupler_force)
            Y.append(sim.y)
        F, Y = np.array(F), np.array(Y)
        stats = sim.integration_stats
        assert stats['steps_max_period'] <= 2 * 100       # twice the default budget
        errors.append(np.abs(F - ref.F).max() / peak)
        if tol == 1e-3:
            assert errors[0] < 0.02, errors
            assert abs(np.abs(F).max() / peak - 1.0) < 0.01
            assert np.abs(Y - ref.y).max() < 0.02 * np.abs(ref.y).max()
    assert errors[1] <= errors[0], errors
