"""Named experiments and presets: which trials to run and which report sections to draw.

An :class:`Experiment` is a list of trials (:class:`benchmarks.trial.TrialSpec`) and the report
sections (:mod:`benchmarks.report`) that present them; a :class:`Preset` is a named list of
experiments. Trials are identified by their key, so experiments that need the same episode
(e.g. ``mpc-acceptance`` and ``paper-tables``) share it within one results directory.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from benchmarks.controllers import (
    CONTROLLERS,
    ENVS,
    N_INITIAL_POINTS,
    RL_ALGORITHMS,
    check_env_scenario,
    check_name,
    learned_term,
)
from benchmarks.trial import Cell, TrialSpec

DEFAULT_CELL = Cell()
"""The scenario as registered."""
MPC_BASES = ("nominal", "gp", "ssgp", "oracle")
"""The four model variants of the paper's tables, in the tables' order."""
MPC_RECEDING = tuple(f"{b}-mpc" for b in MPC_BASES)
MPC_EPISODIC = tuple(f"{b}-episodic" for b in MPC_BASES)


@dataclass(frozen=True)
class Experiment:
    """A set of trials and how the report presents them.

    Attributes:
        name: short name (section anchor, CLI listing).
        title: section title in the report.
        description: what it measures, for the report and ``--list-presets``.
        specs: the trials.
        sections: report section names, in order (see :data:`benchmarks.report.SECTIONS`).
    """

    name: str
    title: str
    description: str
    specs: tuple[TrialSpec, ...]
    sections: tuple[str, ...]


@dataclass(frozen=True)
class Preset:
    """A named list of experiments (one results directory, one report)."""

    name: str
    description: str
    experiments: tuple[Experiment, ...]

    @property
    def specs(self) -> list[TrialSpec]:
        """All trials of all experiments, each once, in order."""
        return list(dict.fromkeys(s for e in self.experiments for s in e.specs))


def episodes(controllers: Iterable[str], envs: Iterable[tuple[str, str]], seeds: Iterable[int],
             max_steps: int | None = None, *, interleave: bool = False, cell: Cell = DEFAULT_CELL,
             n_init: int = N_INITIAL_POINTS) -> tuple[TrialSpec, ...]:
    """Episode trials for every controller x (env, scenario) x seed (in ``cell``, with
    ``n_init`` initial samples for the learning recipes).

    ``interleave``: seed-major order (every controller's episode of a seed, then the next
    seed), so that trials run in order meet a change of the machine's load alike: for
    experiments whose step times are compared as ratios between controllers."""
    envs, seeds, controllers = list(envs), list(seeds), list(controllers)

    def spec(env: str, scenario: str, c: str, s: int) -> TrialSpec:
        return TrialSpec("episode", env, scenario, c, s, max_steps=max_steps, n_init=n_init,
                         cell=cell)

    if interleave:
        return tuple(spec(env, scenario, c, s)
                     for env, scenario in envs for s in seeds for c in controllers)
    return tuple(spec(env, scenario, c, s)
                 for env, scenario in envs for c in controllers for s in seeds)


def custom_experiment(controllers: Sequence[str], envs: Sequence[str],
                      scenarios: Sequence[str] | None, seeds: Sequence[int],
                      max_steps: int | None = None, cell: Cell = DEFAULT_CELL,
                      n_init: int = N_INITIAL_POINTS) -> Experiment:
    """An experiment of a user-chosen grid (``--controllers/--envs/--scenarios/--seeds``, in
    the cell of ``--randomize/--data/--noise/--start`` with ``--n-init`` initial samples).

    ``scenarios=None`` runs each env's default scenario; given scenarios apply to the envs
    that have them (an env with none of them is an error).

    Raises:
        benchmarks.controllers.UnknownNameError: unknown names.
    """
    for c in controllers:
        check_name("controller", c, list(CONTROLLERS))
    pairs: list[tuple[str, str]] = []
    for env in envs:
        check_name("env", env, list(ENVS))
        if scenarios is None:
            pairs.append((env, ENVS[env].default_scenario))
            continue
        own = [s for s in scenarios if s in ENVS[env].scenarios]
        if not own:
            check_env_scenario(env, scenarios[0])  # raises, listing the env's scenarios
        pairs.extend((env, s) for s in own)
    valid = {s for e in ENVS.values() for s in e.scenarios}
    for s in scenarios or ():
        check_name("scenario", s, sorted(valid))
    return Experiment(
        "custom", "Custom run", "A user-chosen grid of controllers x envs x scenarios x seeds "
        "(the controllers interleaved seed by seed).",
        episodes(controllers, pairs, seeds, max_steps, interleave=True, cell=cell,
                 n_init=n_init),
        ("summary", "trajectories", "paths", "step_times"))


# ----------------------------------------------------------------------------- experiments
def paper_tables(seeds: Sequence[int] = tuple(range(10))) -> Experiment:
    """The paper's tables 1 and 2: four models x (episodic, MPC) on cart pole and quadrotor."""
    envs = [(e, s) for e in ("cartpole", "quadrotor") for s in ("gp", "online")]
    return Experiment(
        "paper-tables", "Paper tables 1 and 2 (cart pole, quadrotor)",
        "Nominal vs offline GP vs online SSGP vs oracle (true model), each planned once "
        "(episodic, open loop) and as receding-horizon MPC, on the cart-pole swing-up and the "
        "quadrotor, scenarios `gp` (table 1) and `online` (table 2). Cost is the episode's "
        "cumulative task cost (minus the return).",
        episodes(MPC_RECEDING + MPC_EPISODIC, envs, seeds),
        ("paper_tables", "summary", "trajectories"))


def dubins(seeds: Sequence[int] = tuple(range(50))) -> Experiment:
    """Dubins obstacle avoidance over 50 draws of the nominal model."""
    return Experiment(
        "dubins", "Dubins vehicle around an obstacle (50 episodes)",
        "Each seed's reset draws the nominal actuator losses b1, b2 ~ N(0.3, 0.3) (clipped "
        "at 0.9; true b = 0.3). Nominal MPC vs SSGP-MPC vs oracle MPC; constraint violations "
        "are steps in contact with the obstacle (which end the episode).",
        episodes(("nominal-mpc", "ssgp-mpc", "oracle-mpc"), [("dubins", "paper")], seeds),
        ("summary", "paths"))


SAMPLE_EFFICIENCY_ENVS = (("cartpole", "online"), ("quadrotor", "online"), ("dubins", "paper"))
"""The (env, scenario) pairs the shipped RL models were trained on."""


def sample_efficiency(seeds: Sequence[int] = (0, 1, 2, 3, 4)) -> Experiment:
    """Success and return against env steps used: MPCs vs RL learning curves."""
    return Experiment(
        "sample-efficiency", "Sample efficiency: MPC vs RL",
        "Success rate and return against env steps of interaction: the MPC variants are "
        "points at their interaction before success (initial data + the time the final "
        "stretch held at the goal began, in env steps; where no seed succeeded, the data "
        "used: initial data + the whole episode), SAC/PPO are their training-time learning "
        "curves "
        "(`learning_curve.csv` shipped with each model: deterministic evaluations on reset "
        "seeds 1000..1009) and the final policies evaluated here on the same seeds as the MPCs.",
        episodes((*MPC_RECEDING, *RL_ALGORITHMS), SAMPLE_EFFICIENCY_ENVS, seeds),
        ("sample_efficiency", "summary"))


STEP_SCALING_CONTROLLERS = ("nominal-mpc", "nominal-mpc-rti", "ssgp-mpc-linearized",
                            "ssgp-mpc-rti")
"""The converged and RTI recipes of the compute preset's scaling table: nominal, and SSGP with
the GP linearized per node (converged) or its system's registered RTI learned term (the
quadrotor's: the nominal-pattern linearization)."""
STEP_SCALING_GRID: dict[str, tuple[int, ...]] = {
    "step-vs-nodes": (6, 10, 16, 24),
    "step-vs-horizon": (1000, 1500, 2000, 3000),
    "step-vs-rank": (25, 50, 100, 200),
}
"""Values of each step-scaling trial kind (:data:`benchmarks.compute.STEP_SCALING`)."""
STEP_SCALING_STEPS = 40
"""Closed-loop periods timed per scaling trial."""


def compute(act_samples: Sequence[int] = (200, 1000, 5000),
            ranks: Sequence[int] = (25, 50, 100, 200)) -> Experiment:
    """Per-step compute of every controller; SSGP-MPC scaling with samples and rank; the
    converged and RTI step time against LG nodes, horizon, rank r and samples learned."""
    pairs = [(e, ENVS[e].default_scenario) for e in ENVS]
    specs = episodes((*MPC_RECEDING, *MPC_EPISODIC, *RL_ALGORITHMS), pairs, (0,))
    specs += tuple(TrialSpec("ssgp-act-scaling", "cartpole", "online", "ssgp-mpc", 0, param=n)
                   for n in act_samples)
    specs += tuple(TrialSpec("ssgp-act-scaling", env, scenario, c, 0, param=n)
                   for env, scenario in (("cartpole", "gp"), ("quadrotor", "gp"))
                   for c in ("ssgp-mpc-linearized", "ssgp-mpc-rti") for n in (200, 5000))
    specs += tuple(TrialSpec("ssgp-update-time", "cartpole", "online", "ssgp", 0, param=r)
                   for r in ranks)
    specs += tuple(TrialSpec(kind, env, scenario, c, 0, param=v, max_steps=STEP_SCALING_STEPS)
                   for env, scenario in (("cartpole", "gp"), ("quadrotor", "gp"))
                   for kind, values in STEP_SCALING_GRID.items()
                   for c in STEP_SCALING_CONTROLLERS
                   if kind != "step-vs-rank" or c.startswith("ssgp")
                   for v in values)
    return Experiment(
        "compute", "Compute: per-step time",
        "Wall-clock time of each `act` call (one core, `OMP_NUM_THREADS=1`, seed 0, each env's "
        "default scenario); episodic controllers solve once at the first step and then replay. "
        "SSGP-MPC step time after learning 200 / 1,000 / 5,000 samples (extra samples fed with "
        "`IncrementalSSGP.update`), and the single-sample update time against the rank r. "
        "The scaling table: the converged and RTI step (nominal, and the SSGP with the GP "
        "linearized per node) on the cart pole and quadrotor `gp` (where the nominal RTI's "
        "steps are mostly accepted: on the cart pole `online` its QP is infeasible at most "
        "steps), against the LG "
        "nodes of the receding interval, the horizon, the rank r and 200 vs 5,000 samples "
        f"learned (one setting changed at a time, {STEP_SCALING_STEPS} periods, seed 0).",
        specs, ("step_times", "scaling", "step_scaling", "update_time"))


def peers(seeds: Sequence[int] = tuple(range(10))) -> Experiment:
    """This project's pseudospectral MPC vs do-mpc on the same cart-pole swing-up."""
    return Experiment(
        "peers", "Peers: pseudospectral MPC vs do-mpc",
        "The same cart-pole swing-up problem (scenario `gp`, nominal model, horizon 1.5 s, same "
        "cost, bounds and IPOPT options) solved by this project's Gauss pseudospectral MPC and "
        "by do-mpc (orthogonal collocation), in lockstep in one process per seed (0-9). "
        "Target: at most 0.5x do-mpc's median step time at a closed-loop cost at most do-mpc's "
        "(within 0.5%) on every seed.",
        tuple(TrialSpec("peers", "cartpole", "gp", "ps-vs-do-mpc", s) for s in seeds),
        ("peers",))


def mpc_acceptance(seeds: Sequence[int] = tuple(range(10)),
                   dubins_seeds: Sequence[int] = tuple(range(50))) -> Experiment:
    """The MPC issue's acceptance runs."""
    robust = "ssgp-mpc-linearized-parametric"  # the recipe that held across the envelope
    specs = episodes(("nominal-mpc", "oracle-mpc", "ssgp-mpc", robust), [("cartpole", "online")],
                     seeds)
    specs += episodes(("nominal-mpc", "ssgp-mpc", robust),
                      [("quadrotor", "gp"), ("quadrotor", "online")], seeds)
    specs += episodes(("nominal-mpc", "ssgp-mpc", robust), [("dubins", "paper")], dubins_seeds)
    return Experiment(
        "mpc-acceptance", "MPC acceptance",
        "Cart pole `online`: nominal / oracle / SSGP-MPC on 10 seeds; quadrotor `gp` and "
        "`online`: nominal / SSGP-MPC on 10 seeds (final position error); Dubins: 50 episodes "
        "nominal vs SSGP-MPC (violations, goals reached); each also with the parametric "
        "recipe (ssgp-mpc-linearized-parametric); median act times.",
        specs, ("acceptance", "summary", "step_times"))


def speed_options(seeds: Sequence[int] = tuple(range(10)),
                  quad_seeds: Sequence[int] = tuple(range(5))) -> Experiment:
    """The SSGP-MPC against its two speed variants and the nominal MPC."""
    controllers = ("nominal-mpc", "ssgp-mpc", "ssgp-mpc-nominal-hessian",
                   "ssgp-mpc-model-inputs")
    specs = episodes(controllers, [("cartpole", "online"), ("dubins", "paper")], seeds)
    specs += episodes(controllers, [("quadrotor", "gp")], quad_seeds)
    return Experiment(
        "speed-options", "SSGP-MPC speed options",
        "Two ways to make the SSGP-MPC's step cheaper, each against the SSGP-MPC and the "
        "nominal MPC: *nominal Hessian* drops the GP's second derivatives from the Lagrangian "
        "Hessian (constraints and Jacobian stay exact); *model inputs* feeds the learner only "
        "the states the parametric nominal model's accelerations depend on (quadrotor: 13 "
        "inputs instead of 19; Dubins 4 instead of 6; cart pole 5 instead of 6). Cart pole "
        "`online` and Dubins on 10 seeds, quadrotor `gp` on 5.",
        specs, ("summary", "step_times"))


LINEARIZED_CONTROLLERS = ("nominal-mpc", "ssgp-mpc", "ssgp-mpc-linearized",
                          "ssgp-mpc-linearized-model-inputs")


def linearized(seeds: Sequence[int] = tuple(range(10)),
               dubins_seeds: Sequence[int] = tuple(range(50)),
               act_samples: Sequence[int] = (200, 5000)) -> Experiment:
    """The MPC acceptance runs for the linearized SSGP-MPC, against the exact one and nominal."""
    specs = episodes(LINEARIZED_CONTROLLERS, [("cartpole", "online"), ("quadrotor", "gp"),
                                              ("quadrotor", "online")], seeds)
    specs += episodes(LINEARIZED_CONTROLLERS, [("dubins", "paper")], dubins_seeds)
    specs += tuple(TrialSpec("ssgp-act-scaling", env, scenario, c, 0, param=n)
                   for env, scenario in (("cartpole", "online"), ("quadrotor", "gp"))
                   for c in LINEARIZED_CONTROLLERS[2:] for n in act_samples)
    return Experiment(
        "linearized", "SSGP-MPC with the learned residual linearized per node",
        "The MPC acceptance runs (cart pole `online` and quadrotor `gp`/`online` on 10 seeds, "
        "Dubins on 50) for the nominal MPC, the SSGP-MPC with the GP inside the NLP (exact) "
        "and the SSGP-MPC planning with the GP linearized per collocation node about the warm "
        "start (`learned_dynamics='linearized'`), with all learner inputs and with the model's "
        "inputs only, all in one run so that the step-time ratios compare like with like; and "
        "the linearized recipes' step time after learning 200 vs 5,000 samples.",
        specs, ("acceptance", "summary", "step_times", "scaling"))


RTI_CONTROLLERS = ("nominal-mpc", "nominal-mpc-warm-duals", "nominal-mpc-rti",
                   "nominal-mpc-rti-split", "ssgp-mpc", "ssgp-mpc-rti", "ssgp-mpc-rti-split",
                   "ssgp-mpc-rti-zero-order", "ssgp-mpc-rti-zero-order-split",
                   "ssgp-mpc-rti-parametric", "ssgp-mpc-rti-parametric-split")
"""The converged and real-time-iteration recipes the ``rti`` preset runs on every system
(``ssgp-mpc-rti``: the system's registered learned term), before :func:`rti_controllers`'
alternatives."""
RTI_LEARNED_TERMS = {"linearized": "ssgp-mpc-rti-linearized",
                     "linearized-pattern": "ssgp-mpc-rti-pattern"}
"""The explicit one-call SSGP RTI recipe of each linearized learned term."""


def rti_controllers(system: str) -> tuple[str, ...]:
    """:data:`RTI_CONTROLLERS` and, for each linearized learned term other than ``system``'s
    registered one (which ``ssgp-mpc-rti`` already runs), its explicit recipe, one call and
    split: every term is run once per system, none twice."""
    default = learned_term(CONTROLLERS["ssgp-mpc-rti"], system)
    others = [r for term, r in RTI_LEARNED_TERMS.items() if term != default]
    return (*RTI_CONTROLLERS, *(f"{r}{tail}" for r in others for tail in ("", "-split")))


def rti(seeds: Sequence[int] = tuple(range(10)),
        dubins_seeds: Sequence[int] = tuple(range(50)),
        act_samples: Sequence[int] = (200, 5000)) -> Experiment:
    """The MPC acceptance runs with the real-time iteration next to the converged MPC."""
    specs = episodes((*rti_controllers("cartpole"), "oracle-mpc", "oracle-mpc-warm-duals",
                      "oracle-mpc-rti", "oracle-mpc-rti-split"), [("cartpole", "online")],
                     seeds, interleave=True)
    specs += episodes(rti_controllers("quadrotor"), [("quadrotor", "gp"), ("quadrotor", "online")],
                      seeds, interleave=True)
    specs += episodes(rti_controllers("dubins"), [("dubins", "paper")], dubins_seeds,
                      interleave=True)
    specs += tuple(TrialSpec("ssgp-act-scaling", env, scenario, c, 0, param=n)
                   for c in ("ssgp-mpc-rti", "ssgp-mpc-rti-parametric")
                   for env, scenario in (("cartpole", "online"), ("quadrotor", "gp"),
                                         ("dubins", "paper"))
                   for n in act_samples)
    return Experiment(
        "rti", "Real-time iteration against the converged MPC",
        "The MPC acceptance runs (cart pole `online` and quadrotor `gp`/`online` on 10 seeds, "
        "Dubins on 50) for the nominal, oracle (cart pole) and SSGP-MPC, each converged "
        "(`scheme='converged'`; nominal and oracle also with warm-started multipliers, "
        "`warm_start_duals=True`, the faster converged reference) and as a real-time "
        "iteration (`scheme='rti'`: a converged cold start, then one Gauss-Newton SQP step "
        "per period; the SSGP one with the system's registered learned term, "
        "`PlanningDefaults.rti_learned_dynamics`, and the other linearized term explicitly: "
        "the GP linearized per node at the shifted plan, `linearized`, or linearized on the "
        "nominal model's Jacobian pattern with the dropped derivatives adjoint-corrected, "
        "`pattern`; and with its value frozen per node and the gradient adjoint-corrected, "
        "`zero-order`), "
        "each RTI also split into a preparation after the action and a feedback phase on the "
        "measurement (`-split`, `scheme='rti-split'`: its latency is the act time minus the "
        "preparation), all in one run, the recipes interleaved seed by seed, so that the "
        "step-time ratios compare like with like; "
        "and the SSGP RTI's step time after learning 200 vs 5,000 samples. Targets: nominal "
        "RTI step at most 0.15x the converged one (reported against both converged "
        "references); SSGP RTI at most 1.5x the nominal RTI; the same successes as the "
        "converged MPC.",
        specs, ("acceptance", "summary", "step_times", "scaling"))


def pendulum(seeds: Sequence[int] = tuple(range(1, 11))) -> Experiment:
    """The fourth system, registered in one file (:mod:`gp_envs.pendulum_swingup`)."""
    controllers = ("nominal-mpc", "ssgp-mpc", "ssgp-mpc-linearized", "oracle-mpc",
                   "nominal-mpc-rti", "ssgp-mpc-rti")
    return Experiment(
        "pendulum", "Pendulum swing-up: a system added in one file",
        "The damped pendulum (`gp_envs/PendulumSwingUp-v0`, scenario `damped`: unmodeled pivot "
        "friction and a 10% mass error), registered by one `register_system` call next to "
        "its env class, run by the same recipes as the paper's systems: nominal, SSGP (GP in "
        "the NLP, and linearized), oracle MPC and the real-time iterations, on seeds 1-10 "
        "(seed 0 chose the registered horizon).",
        episodes(controllers, [("pendulum", "damped")], seeds),
        ("summary", "trajectories", "step_times"))


ROBUSTNESS_CONTROLLERS = ("nominal-mpc", "ssgp-mpc", "ssgp-mpc-linearized",
                          "ssgp-mpc-sensitivities", "ssgp-mpc-linearized-sensitivities",
                          "ssgp-mpc-adaptive", "ssgp-mpc-linearized-adaptive",
                          "ssgp-mpc-linearized-guarded", "ssgp-mpc-linearized-saturated",
                          "ssgp-mpc-linearized-parametric", "ssgp-mpc-rti-parametric-split",
                          "oracle-mpc")
"""The controllers of the robustness envelope (the oracle is each cell's reference)."""
ROBUSTNESS_SEEDS = tuple(range(200, 220))
"""Evaluation seeds of the robustness preset: never used to tune anything (the issue's own
diagnosis used 101-105; development uses 0-9)."""
ROBUSTNESS_NOISE = 0.005
"""Observation noise of the noisy cells: 5 mm, 5 mrad, 5 mm/s, 5 mrad/s standard deviation."""


def robustness(seeds: Sequence[int] = ROBUSTNESS_SEEDS,
               dubins_seeds: Sequence[int] = tuple(range(200, 250)),
               n_inits: Sequence[int] = (50, 100, 200),
               kappas: Sequence[float] = (0.0, 1.0, 2.0, 3.0)) -> Experiment:
    """The online-learning envelope: randomized truth with the initial data from the system
    controlled or from another draw, perturbed starts, measurement noise, time-varying truth,
    fewer initial samples, and the Dubins uncertainty radius."""
    randomized = [Cell(randomize=r, data=d) for r in (0.05, 0.1, 0.2) for d in ("same", "diff")]
    noisy = Cell(noise=ROBUSTNESS_NOISE)
    grid = [
        ("cartpole", "online", [Cell(), *randomized, Cell(start="perturbed"), noisy], seeds),
        ("cartpole", "online-wear", [Cell()], seeds),
        ("quadrotor", "online", [Cell(), Cell(randomize=0.1), Cell(randomize=0.1, data="diff"),
                                 Cell(start="perturbed"), noisy], seeds),
        ("quadrotor", "online-payload", [Cell()], seeds),
        ("dubins", "paper", [Cell(), Cell(randomize=0.1), Cell(randomize=0.1, data="diff"),
                             noisy], dubins_seeds),
        ("dubins", "paper-wear", [Cell()], dubins_seeds),
    ]
    specs = tuple(TrialSpec("episode", env, scenario, c, s, cell=cell)
                  for env, scenario, cells, env_seeds in grid for cell in cells
                  for c in ROBUSTNESS_CONTROLLERS for s in env_seeds)
    specs += tuple(TrialSpec("episode", env, scenario, c, s, n_init=n)
                   for c in ("ssgp-mpc", "ssgp-mpc-linearized-parametric")
                   for env, scenario, env_seeds in (("cartpole", "online", seeds),
                                                    ("quadrotor", "online", seeds),
                                                    ("dubins", "paper", dubins_seeds))
                   for n in n_inits for s in env_seeds
                   if n != N_INITIAL_POINTS)  # the default is the fixed-truth cell's trial
    # the kappa cells plan with the GP linearized per node: with the GP and its variance
    # inside the NLP kappa-1 episodes took 4-5 min each in an ad-hoc look (50 samples, a
    # loaded machine), the linearized ones ~3.4 s (benchmarks/results/robustness-dubins-kappa)
    kappa_cells = [Cell(randomize=0.1), Cell(noise=ROBUSTNESS_NOISE)]
    specs += tuple(TrialSpec("episode", "dubins", "paper", "ssgp-mpc-linearized", s, n_init=n,
                             cell=Cell(randomize=cell.randomize, noise=cell.noise, kappa=k))
                   for k in kappas for cell in kappa_cells for n in (50, 200)
                   for s in dubins_seeds)
    return Experiment(
        "robustness", "Online learning across the envelope",
        "Nominal, SSGP (GP in the NLP, and linearized; each also with the parameter "
        "sensitivities as inputs and linear features, and with those and a change detector) "
        "and oracle MPC on randomized truth "
        "(spread 0.05, 0.1, 0.2; initial data from the system controlled, *same*, or from an "
        "independent draw, *diff*), perturbed starts, observation noise "
        f"({ROBUSTNESS_NOISE:g} per component), and the time-varying scenarios (cart pole "
        "`online-wear`: damping doubles at 3 s; quadrotor `online-payload`: +20% mass at "
        "3 s; Dubins `paper-wear`: losses 1.5x at 5 s, 2x at 10 s); the SSGP-MPC with 50, "
        "100 and 200 initial samples; the Dubins SSGP-MPC (linearized) against the "
        "uncertainty radius kappa. Evaluation seeds 200-219 (Dubins 200-249), never used "
        "for tuning.",
        tuple(dict.fromkeys(specs)), ("robustness", "summary"))


def quick() -> Experiment:
    """A couple of minutes: the main controllers on every env, one or two seeds."""
    ssgp = ("ssgp-mpc", "ssgp-mpc-linearized", "robust-mpc")
    specs = episodes(("nominal-mpc", "gp-mpc", *ssgp, "oracle-mpc", "sac", "tqc"),
                     [("cartpole", "online")], (0, 1))
    specs += episodes(("nominal-mpc", *ssgp, "oracle-mpc", "ppo"), [("quadrotor", "online")],
                      (0,))
    specs += episodes(("nominal-mpc", *ssgp, "oracle-mpc", "ppo"), [("dubins", "paper")],
                      (0, 1))
    specs += episodes(("nominal-mpc", "ssgp-mpc", "oracle-mpc"), [("pendulum", "damped")], (1,))
    specs += tuple(TrialSpec("ssgp-update-time", "cartpole", "online", "ssgp", 0, param=r)
                   for r in (25, 50, 100))
    specs += (TrialSpec("peers", "cartpole", "gp", "ps-vs-do-mpc", 0),)
    return Experiment(
        "quick", "Quick comparison",
        "Nominal, offline-GP, SSGP (GP in the NLP, linearized per node, and the robust "
        "recipe as `make_mpc(env)` plans: IPOPT on the cart pole, the SQP on the quadrotor and "
        "the Dubins vehicle) and oracle MPC and the shipped SAC and TQC policies on the cart "
        "pole (`online`, seeds 0-1); nominal, the SSGP MPCs and "
        "oracle MPC and PPO on the quadrotor "
        "(`online`, seed 0) and the Dubins vehicle (seeds 0-1); nominal, SSGP and oracle MPC "
        "on the pendulum (`damped`, seed 1); SSGP update time for r = 25, "
        "50, 100; one episode each of this project's MPC and do-mpc (if installed).",
        specs, ("summary", "trajectories", "paths", "step_times", "sample_efficiency",
                "update_time", "peers"))


RECOMMENDED_SEEDS = tuple(range(400, 420))
"""Evaluation seeds of the recommended preset: used by no other preset and for no tuning."""


def recommended(seeds: Sequence[int] = RECOMMENDED_SEEDS,
                dubins_seeds: Sequence[int] = tuple(range(400, 450)),
                randomize: float = 0.1) -> Experiment:
    """The recommended recipe as a user runs it: ``make_mpc(env)`` pretrained on
    ``collect_initial_data(env, 200, seed=s)`` on a randomized truth, against the oracle."""
    cell = Cell(randomize=randomize, data="own")
    controllers = ("robust-mpc", "oracle-mpc")
    specs = episodes(controllers, [("cartpole", "online"), ("quadrotor", "online")], seeds,
                     interleave=True, cell=cell)
    specs += episodes(controllers, [("dubins", "paper")], dubins_seeds, interleave=True,
                      cell=cell)
    return Experiment(
        "recommended", "The recommended recipe as a user runs it",
        f"`make_mpc(env)` (the robust recipe) pretrained on `collect_initial_data(env, 200, "
        f"seed=s)` (the system `env.reset(seed=s)` gives) against the oracle MPC, on a "
        f"randomized truth (each true parameter x (1 + U(-{randomize:g}, {randomize:g})) per "
        f"seed), evaluation seeds no preset or tuning used.",
        specs, ("summary", "trajectories", "paths"))


DATA_EFFICIENCY_SEEDS = tuple(range(500, 510))
"""Evaluation seeds of the data-efficiency preset (issue 44): used by no other preset and for no
tuning (its study, ``benchmarks/studies/data_efficiency.py``, tuned on seeds 0-19)."""
DATA_EFFICIENCY_N_INIT = (0, 5, 10, 20, 50, 100, 200)
"""Initial samples of the learning recipes (0: learned from the first step, planning with the
model alone until the first transition: ``agent.pretrain(None)``)."""
DATA_EFFICIENCY_LEARNERS = ("robust-mpc", "paper-mpc", "blackbox-mpc", "parametric-mpc")
"""The learning recipes of the data-efficiency preset (nominal and oracle are its references)."""
DATA_EFFICIENCY_ENVS = (("pilco_cartpole", "pilco"), ("cartpole", "online"),
                        ("pendulum", "damped"), ("quadrotor", "online"), ("dubins", "paper"))
"""Its (env, scenario) pairs, in the order they run (PILCO's cart pole and the cart pole
first)."""


def data_efficiency(seeds: Sequence[int] = DATA_EFFICIENCY_SEEDS,
                    n_inits: Sequence[int] = DATA_EFFICIENCY_N_INIT,
                    envs: Sequence[tuple[str, str]] = DATA_EFFICIENCY_ENVS) -> Experiment:
    """Success, cost and interaction time before success against the data used, with a
    multi-trial protocol (``kind="trials"``, :func:`benchmarks.trial.run_trials`)."""
    cell = Cell(data="own")
    specs: list[TrialSpec] = []
    for env, scenario in envs:
        specs += [TrialSpec("trials", env, scenario, c, s, n_init=0, cell=cell)
                  for c in ("nominal-mpc", "oracle-mpc") for s in seeds]
        specs += [TrialSpec("trials", env, scenario, c, s, n_init=n, cell=cell)
                  for n in n_inits for c in DATA_EFFICIENCY_LEARNERS for s in seeds]
    return Experiment(
        "data-efficiency", "Data efficiency: success against the data used",
        "Nominal, paper (online SSGP in the NLP), robust (parametric SSGP, linearized), "
        "black-box (no physics prior: kinematics only, the SSGP learns every acceleration), "
        "parametric (the grey box: recursive least squares on the parameter sensitivities, no "
        "GP) and oracle MPC, the learners with 0, 5, 10, 20, 50, 100 and 200 initial samples "
        "collected as a user does (`collect_initial_data(env, n, seed=s)`: PILCO's cart pole "
        "applies uniform random forces, as PILCO's first random trial; the other systems their "
        "crude tracking controller), on evaluation seeds "
        f"{seeds[0]}-{seeds[-1]}. *Interaction time before success*: the initial data's time "
        "plus the time at which the final stretch held at the goal began "
        "(`info['at_goal_since']` at the episode's end). Multi-trial protocol (GP-MPC's): a "
        "learning recipe that has not succeeded runs another trial, up to 5, on the same "
        "system from a new start, its agent pretrained on every transition so far.",
        tuple(specs), ("data_efficiency", "summary"))


OWN_ENV_SEEDS = tuple(range(2000, 2010))
"""Evaluation seeds of the own-env preset: used by no other preset and for no tuning (the
choices it rests on were made on Pendulum-v1 seeds 1000-1009 and DMC cart-pole seeds 0-9:
``docs/studies/own_env.md``)."""
OWN_ENV_LEARNERS = ("robust-mpc", "paper-mpc", "blackbox-mpc", "parametric-mpc")
"""The learning recipes of the own-env preset."""


def own_env(seeds: Sequence[int] = OWN_ENV_SEEDS) -> Experiment:
    """Outside simulators through :func:`gp_envs.wrap` (:mod:`benchmarks.outside_envs`):
    Gymnasium's Pendulum-v1 with a nominal mass 60% low, and DeepMind Control's cart-pole
    swing-up (MuJoCo) at 0.05 s with 0-200 initial samples, at DMC's own 0.01 s, and with the
    declared out-of-family friction; data collected as a user does
    (``collect_initial_data(env, n, seed=s)``)."""
    cell = Cell(data="own")
    references = ("nominal-mpc", "oracle-mpc", "sac")

    def grid(env: str, scenario: str, n_inits: Sequence[int],
             refs: Sequence[str] = references) -> list[TrialSpec]:
        out = [TrialSpec("episode", env, scenario, c, s, n_init=0, cell=cell)
               for c in refs for s in seeds]
        out += [TrialSpec("episode", env, scenario, c, s, n_init=n, cell=cell)
                for n in n_inits for c in OWN_ENV_LEARNERS for s in seeds]
        return out

    specs = [*grid("pendulum-v1", "light", (100,)),
             *grid("dmc-cartpole", "swingup", (0, 20, 50, 200)),
             *grid("dmc-cartpole", "swingup-friction", (200,), ("nominal-mpc", "sac")),
             *grid("dmc-cartpole", "swingup-0.01", (1000,), ("nominal-mpc",))]
    return Experiment(
        "own-env", "Your env, your simulator: outside truths through gp_envs.wrap",
        "Gymnasium's Pendulum-v1 (its own step, speed clip and reward; the nominal model's "
        "mass 60% low; the oracle plans with the correct mass) with 100 initial samples, and "
        "DeepMind Control's cartpole/swingup (MuJoCo physics and reward untouched; nominal: "
        "the package's point-mass cart pole with cartpole.xml's numbers) at a 0.05 s control "
        "period (action repeat 5) with 0, 20, 50 and 200 initial samples, with the declared "
        "out-of-family Coulomb friction (gp_envs.dmc.CARTPOLE_FRICTION), and at DMC's own "
        "0.01 s with 1000; the learning recipes' data as a user collects them, on evaluation "
        f"seeds {seeds[0]}-{seeds[-1]}. What answers: does the package's recommended recipe "
        "reach the published returns on a truth it did not write, and does any learning recipe "
        "end below the nominal MPC it starts from.",
        tuple(specs), ("own_env", "summary"))


PRESETS: dict[str, Preset] = {
    "quick": Preset("quick", "a couple of minutes: the main controllers on every env",
                    (quick(),)),
    "recommended": Preset("recommended", "make_mpc(env) as a user runs it, randomized truth, "
                          "against the oracle", (recommended(),)),
    "paper-tables": Preset("paper-tables", "the paper's tables 1 and 2, seeds 0-9",
                           (paper_tables(),)),
    "dubins": Preset("dubins", "Dubins obstacle avoidance, 50 episodes", (dubins(),)),
    "sample-efficiency": Preset("sample-efficiency", "MPC data use vs RL learning curves",
                                (sample_efficiency(),)),
    "compute": Preset("compute", "per-step times, SSGP scaling with samples and rank",
                      (compute(),)),
    "peers": Preset("peers", "pseudospectral MPC vs do-mpc (needs do-mpc)", (peers(),)),
    "mpc-acceptance": Preset("mpc-acceptance", "the MPC issue's acceptance runs",
                             (mpc_acceptance(),)),
    "speed-options": Preset("speed-options", "SSGP-MPC speed variants (not part of full)",
                            (speed_options(),)),
    "linearized": Preset("linearized", "acceptance runs of the linearized SSGP-MPC "
                         "(not part of full)", (linearized(),)),
    "pendulum": Preset("pendulum", "the fourth system, added in one file (not part of full)",
                       (pendulum(),)),
    "robustness": Preset("robustness", "online learning across randomized, noisy and "
                         "time-varying systems (long; not part of full)", (robustness(),)),
    "rti": Preset("rti", "real-time iteration vs converged MPC, with the peers comparison "
                  "(not part of full)", (rti(), peers())),
    "data-efficiency": Preset("data-efficiency", "success and interaction time against the "
                              "data used, with PILCO's and GP-MPC's published figures (long; "
                              "not part of full)", (data_efficiency(),)),
    "own-env": Preset("own-env", "outside simulators through gp_envs.wrap: Pendulum-v1 and "
                      "DeepMind Control's cart-pole (needs the mujoco extra; not part of full)",
                      (own_env(),)),
    "full": Preset("full", "everything: all experiments above except quick",
                   (paper_tables(), dubins(), sample_efficiency(), compute(), peers(),
                    mpc_acceptance())),
}
"""Presets by name."""


def get_preset(name: str) -> Preset:
    """The preset ``name``; unknown names raise with the list of valid ones."""
    check_name("preset", name, list(PRESETS))
    return PRESETS[name]
