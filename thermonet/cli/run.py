"""``thermonet run``: run a scene (default: the built-in 3D truss block), write its ParaView
time series, diagnostics, summary and checkpoints, and print the conservation summary."""

from __future__ import annotations

import os
import sys

HELP = "run a scene and write VTU/PVD frames, diagnostics.csv, summary.json and checkpoints"


def add_args(p) -> None:
    p.add_argument("scene", nargs="?", default=None,
                   help="scene file (.toml); default: the built-in 3D truss block (scenes/default.toml)")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="output folder (default: the scene's output.folder, or thermonet-out/<name>)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="overrides",
                   help="override a scene key, e.g. --set integrator.h=1e-4 --set effects.gravity=false "
                        "(the value is read as TOML; repeatable)")
    p.add_argument("--resume", default=None, metavar="CHECKPOINT",
                   help="continue from a checkpoint (.npz file, or the output folder holding it); "
                        "the result is bit-for-bit that of an uninterrupted run")
    p.add_argument("--integrator", default=None, help="shorthand for --set integrator.name=NAME")
    p.add_argument("--h", type=float, default=None, help="shorthand for --set integrator.h=H")
    p.add_argument("--t-end", type=float, default=None, help="shorthand for --set integrator.t_end=T")
    p.add_argument("--allow-unstable-step", action="store_true",
                   help="run even when h is far above the estimated stability limit (> 1.5 h_max; "
                        "same as --set integrator.check_step=false); it is still warned about")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")


def overrides_of(args) -> list[str]:
    """``--set`` items plus the shorthands, in that order (shorthands win)."""
    items = list(args.overrides or [])
    if args.integrator is not None:
        items.append(f'integrator.name="{args.integrator}"')
    if args.h is not None:
        items.append(f"integrator.h={args.h!r}")
    if args.t_end is not None:
        items.append(f"integrator.t_end={args.t_end!r}")
    return items


def handle(args) -> int:
    from ..errors import SimulationError
    from ..io import RunOutput, load_checkpoint
    from ..scenes import load_scene, scene_from_text
    from .progress import ProgressBar
    from .report import format_summary

    overrides = overrides_of(args)
    state = meta = None
    if args.resume:
        checkpoint = args.resume
        if os.path.isdir(checkpoint):
            found = sorted(f for f in os.listdir(checkpoint) if f.endswith(".checkpoint.npz"))
            if not found:
                from ..errors import InputError

                raise InputError(f"{checkpoint}: no *.checkpoint.npz in this folder")
            checkpoint = os.path.join(checkpoint, found[0])
        state, meta = load_checkpoint(checkpoint)
        saved = meta["scene"]
        if args.scene:
            scene = load_scene(args.scene, overrides)
        else:
            scene = scene_from_text(saved["text"], file=saved["file"], base_dir=saved["base_dir"],
                                    overrides=list(saved["overrides"]) + overrides)
        if scene.hash != saved["hash"]:
            from ..errors import InputError

            raise InputError(f"{checkpoint}: written by a different scene (hash {saved['hash'][:12]}, this scene "
                             f"{scene.hash[:12]}): net, materials, initial state, effects or integrator differ")
        folder = args.out or os.path.dirname(os.path.abspath(checkpoint))
    else:
        scene = load_scene(args.scene, overrides)
        folder = args.out or scene["output"].get("folder") or os.path.join("thermonet-out", scene.name)

    built = scene.build()
    sim = built.simulation
    if state is None:
        _check_step(sim, scene, args)
    total = scene.total_steps()
    output = RunOutput(
        sim, folder, scene.name,
        fields=scene.output_fields(),
        frames_every=scene.cadence("frames_every", total),
        diagnostics_every=scene.cadence("diagnostics_every", total),
        checkpoint_every=scene.cadence("checkpoint_every", total),
        material_id=built.material_id,
        scene=scene.describe(),
    )
    if state is not None:
        sim.load_state(state)
        output.restore(meta)
    progress = None if args.quiet else ProgressBar()
    try:
        sim.run(steps=max(0, total - sim.step), diagnostics_every=output.diagnostics_every,
                observers=output.observers(), progress=progress)
    except BaseException as exc:
        if progress:
            progress.close()
        if isinstance(exc, SimulationError) and output.checkpoint_every:
            output.write_checkpoint(sim)  # the last good state (the run was rewound to it)
        output.write_csv()
        if not args.quiet and output.checkpoint_every and os.path.exists(output.checkpoint_path):
            print(f"thermonet: stopped at step {sim.step}; continue with: thermonet run --resume {output.checkpoint_path}",
                  file=sys.stderr)
        raise
    if progress:
        progress.close()
    output.write_csv()
    output.write_summary(sim)
    if not args.quiet:
        print(format_summary(sim, scene.name, folder))
        files = [f"{scene.name}.pvd ({len(output.pvd.frames)} frames)" if output.frames_every else None,
                 "diagnostics.csv", "summary.json",
                 os.path.basename(output.checkpoint_path) if output.checkpoint_every else None]
        print(f"  wrote {', '.join(f for f in files if f)}")
    return 0


def _check_step(sim, scene, args) -> None:
    """The step-limit policy (thermonet.step_policy) at the initial state: refuse (an InputError)
    or warn on stderr."""
    import warnings

    from ..step_policy import StepWarning, check_step

    allow = args.allow_unstable_step or not scene["integrator"]["check_step"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StepWarning)
        verdict = check_step(sim, allow_unstable=allow, warn=False)
    if verdict.message and not args.quiet:
        print(f"thermonet: warning: {verdict.message}", file=sys.stderr)
