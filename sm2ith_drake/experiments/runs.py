"""A campaign's runs: what identifies one (RunSpec), the plan of a study
(cells × variants × people models × methods × seeds, every method on the
same seeds), and the Scenario a run simulates.
"""

from __future__ import annotations

import dataclasses

from sm2ith_drake.experiments.people import (
    AS_SCENARIO,
    PEOPLE_MODELS,
    ApplyPeopleModel,
    ApplySeed,
    DoorwayPeople,
    MergeYaml,
    VariantText,
)
from sm2ith_drake.experiments.studies import Study
from sm2ith_drake.scenario_loader import LoadScenario


@dataclasses.dataclass(frozen=True)
class RunSpec:
    study: str
    family: str
    robot: str
    humans: int
    method: str
    seed: int
    scenario_file: str
    scenario: str
    # The method's and the variant's YAML overrides, merged.
    scenario_text: str
    variant: str = "safe"
    people: str = AS_SCENARIO
    # Simulated-time cap (s); 0: the scenario's own duration.
    duration: float = 0.0
    # The cell's people sampler (None: the scenario's people, ApplySeed).
    sampler: DoorwayPeople | None = None

    @property
    def cell(self) -> str:
        if self.sampler is None:
            return self.scenario
        return f"{self.scenario}_{self.humans}h"

    @property
    def run_id(self) -> str:
        return f"{self.cell}/{self.variant}/{self.people}/{self.method}/seed{self.seed}"


def PlanRuns(
    study: Study,
    *,
    runs: int | None = None,
    only: str | None = None,
    duration: float = 0.0,
    variants: tuple | list | None = None,
    people: tuple | list | None = None,
    scenario_text: str = "",
    methods: tuple | list | None = None,
) -> list[RunSpec]:
    """The study's runs: every cell × variant × people model × method × seed,
    every method on the same seeds (paired).

    Args:
        runs: seeds per method and cell (default: the study's, 10).
        only: keep the cells whose name contains this text.
        duration: cap on each run's simulated time (0: the scenario's).
        variants: safety variants (default: the study's), from VARIANTS.
        people: people models (default: the study's), from PEOPLE_MODELS
            (or "scenario": the scenario's own behaviours).
        scenario_text: YAML applied to every run under the method's and the
            variant's overrides (which win where they overlap): one change,
            made alike for every method, e.g. '{safety: {guard_gap: 0.1}}'.
        methods: run only these of the study's methods (default: all),
            e.g. to re-run one method after a change that only it sees.
    """
    variants = tuple(study.variants if variants is None else variants)
    people = tuple(study.people if people is None else people)
    for v in variants:
        VariantText(v)  # raises on an unknown variant
    for p in people:
        if p not in PEOPLE_MODELS + (AS_SCENARIO,):
            raise ValueError(
                f"unknown people model {p!r}; valid: "
                + ", ".join(PEOPLE_MODELS + (AS_SCENARIO,))
            )
    names = [m.name for m in study.methods]
    unknown = [m for m in methods or () if m not in names]
    if unknown:
        raise ValueError(
            f"study {study.name} has no method {', '.join(unknown)}; "
            "valid: " + ", ".join(names)
        )
    seeds = study.seeds if runs is None else runs
    specs = []
    for cell in study.cells:
        if only and only not in cell.name:
            continue
        for variant in variants:
            for model in people:
                for method in study.methods:
                    if methods and method.name not in methods:
                        continue
                    text = MergeYaml(
                        scenario_text, method.scenario_text, VariantText(variant)
                    )
                    for seed in range(seeds):
                        specs.append(
                            RunSpec(
                                study=study.name,
                                family=cell.family,
                                robot=cell.robot,
                                humans=cell.humans,
                                method=method.name,
                                seed=seed,
                                scenario_file=cell.scenario_file,
                                scenario=cell.scenario,
                                scenario_text=text,
                                variant=variant,
                                people=model,
                                duration=duration,
                                sampler=cell.people,
                            )
                        )
    return specs


def LoadRunScenario(spec: RunSpec):
    """The Scenario of a run: the cell's scenario, the method's and the
    variant's overrides, the seed's people in the run's people model."""

    scenario = LoadScenario(
        filename=spec.scenario_file,
        scenario_name=spec.scenario,
        scenario_text=spec.scenario_text,
    )
    if spec.sampler is not None:
        scenario = spec.sampler(scenario, spec.humans, spec.seed)
    else:
        scenario = ApplySeed(scenario, spec.seed)
    return ApplyPeopleModel(scenario, spec.people)


def SpecFromRow(study: Study, row: dict) -> RunSpec:
    """The RunSpec of a CSV row of ``study`` (to replay it)."""
    cell = next(
        (
            c
            for c in study.cells
            if c.scenario == row["scenario"] and c.humans == int(row["humans"])
        ),
        None,
    )
    if cell is None:
        raise ValueError(
            f"study {study.name} has no cell {row['scenario']} with "
            f"{row['humans']} people"
        )
    return RunSpec(
        study=study.name,
        family=cell.family,
        robot=cell.robot,
        humans=cell.humans,
        method=row["method"],
        seed=int(row["seed"]),
        scenario_file=row["scenario_file"],
        scenario=row["scenario"],
        scenario_text=row["scenario_text"],
        variant=row.get("variant") or "safe",
        people=row.get("people") or AS_SCENARIO,
        duration=float(row.get("duration") or 0.0),
        sampler=cell.people,
    )
