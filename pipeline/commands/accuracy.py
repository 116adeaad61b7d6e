"""``fisheye-des accuracy``: measure the fusion filter against the issue's numbers on simulated scenes.

Prints one table (ours, the thesis's two-frame law-of-sines method, the target, a verdict) and, with
``--out DIR``, writes ``DIR/accuracy.json`` (every metric, per scene) and ``DIR/accuracy.txt``.
``--set heldout`` scores the held-out scenes instead (``accuracy_heldout.*``), ``--set validation``
the 18 fresh-seed validation scenes (``accuracy_validation.*``), ``--set both`` tuned and held-out
side by side (``accuracy_both.*``), ``--set demo`` the scene of ``fisheye-des demo`` rendered as the
demo renders it, ``--set lowres`` 640x360 copies of six scenes (lens scaled), ``--set highfps``
100-fps copies of four scenes, ``--set rig360`` the top/bottom 360-degree pair in two climbing flights,
``--set all`` tuned, held-out, validation, demo, lowres, highfps and rig360.
``--override section.key=value`` sets a config key for every scene's run (``fisheye-des run
--set``'s grammar), e.g.
``--override tracker.grouping.link_px=30``; pipeline mode keeps scene renders in
``~/.cache/fisheye-des/accuracy`` (``--no-render-cache``: in ``--out`` as before).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def register(app: typer.Typer) -> None:
    """Add the ``accuracy`` sub-command to ``app``."""

    @app.command("accuracy")
    def accuracy_cmd(
        quick: Annotated[
            bool, typer.Option("--quick", help="Few short scenes (CI smoke test, < 1 min).")
        ] = False,
        mode: Annotated[
            str,
            typer.Option("--mode", help="bearings (true bearings + noise) or pipeline (render, track)."),
        ] = "bearings",
        out: Annotated[
            Path | None, typer.Option("--out", help="Write accuracy.json / accuracy.txt here.")
        ] = None,
        pixel_sigma: Annotated[
            float | None,
            typer.Option("--pixel-sigma", help="Bearings mode: pixel noise (px, 1-sigma; default 0.5)."),
        ] = None,
        seed: Annotated[
            int | None,
            typer.Option("--seed", help="Bearings mode: seed of the noise and of the random scenes "
                         "(default 0)."),
        ] = None,
        n_random: Annotated[
            int | None,
            typer.Option("--n-random", help="Bearings mode: random scenes per family (default 1 quick, "
                         "6 full)."),
        ] = None,
        thesis_interval: Annotated[
            float,
            typer.Option("--thesis-interval", help="Frame interval (s) of the thesis's two-frame method."),
        ] = 0.5,
        max_speed: Annotated[
            float | None,
            typer.Option(
                "--max-speed", help="Max obstacle speed (m/s) for the bounds; default: the drone's speed."
            ),
        ] = None,
        scene: Annotated[
            list[str] | None,
            typer.Option("--scene", help="Only this scene of the chosen --set (repeat); default: all of it."),
        ] = None,
        scene_set: Annotated[
            str,
            typer.Option(
                "--set",
                help="Scene set: tuned (default: the scenes the fusion and grouping settings were "
                "fitted on), heldout (configs/scenarios/heldout_*.yaml, used to fit nothing), validation "
                "(configs/scenarios/val_*.yaml and val2_*.yaml: 18 fresh-seed copies of the five held-out "
                "scenes and mono_straight, moving_crossing, stereo_flying, turning; used to fit nothing; "
                "no --quick scenes in pipeline mode), both (tuned and heldout: each table, then side by "
                "side and per scene), demo (configs/scenarios/demo.yaml as `fisheye-des demo` renders "
                "it: its resolution, grey videos for a grey detector; no --quick scenes), lowres "
                "(lowres_<scene>: 640x360 copies, lens scaled, of mono_straight, moving_crossing and four "
                "stereo flying scenes; used to fit nothing; no --quick scenes), highfps (fps100_<scene>: "
                "100-fps copies of mono_straight, moving_crossing, stereo_flying and heldout_stereo_flying; "
                "used to fit nothing; no --quick scenes), rig360 (top_bottom_climb, top_bottom_turn: the "
                "chapter-5 top/bottom 360-degree pair, its one-camera reports scored as monocular, no "
                "stereo rows; used to fit nothing; no --quick scenes) or all (tuned, heldout, validation, "
                "demo, lowres, highfps, rig360). Pipeline mode also prints each set's pooled range z^2 "
                "(median, mean without the top 1 %, share > 9), its top 10 z^2 reports and the range "
                "error of every report the demo scores (confirmed, on an obstacle, any age). With --out, "
                "a set other than tuned writes accuracy_<set>.json / .txt.",
            ),
        ] = "tuned",
        override: Annotated[
            list[str] | None,
            typer.Option(
                "--override",
                help="Override a config key for every scene's run: section.key=value (repeat), the "
                "grammar of `fisheye-des run --set`, e.g. --override tracker.grouping.link_px=30 or "
                "--override fusion.feature_point_sigma_k=2.5. Checked before anything runs. Front-end "
                "sections (detector, tracker, ...) change the --reuse-frontend recording key, so a "
                "changed front end is tracked again, not replayed. --max-speed wins over "
                "fusion.max_speed_mps.",
            ),
        ] = None,
        render_cache: Annotated[
            bool | None,
            typer.Option(
                "--render-cache/--no-render-cache",
                help="Pipeline mode: keep scene renders in ~/.cache/fisheye-des/accuracy "
                "($XDG_CACHE_HOME), one folder <scene>-<key> per parsed scenario and simulator "
                "version, linked into --out/scenes and reused by every later run (delete the folder "
                "to render again). --no-render-cache renders into --out/scenes (reused there while "
                "the scenario text and length are unchanged). A render already in --out/scenes from "
                "an earlier run is used either way when its scenario text matches. Default: render-cache.",
            ),
        ] = None,
        reuse_frontend: Annotated[
            bool,
            typer.Option(
                "--reuse-frontend",
                help="Pipeline mode: replay the fusion over the front end's observations recorded by an "
                "earlier run into the same --out (runs/<scene>/observations.pkl) instead of tracking again; "
                "a recording made with other trackers/ sources, --quick, scenario text or front-end "
                "config is recorded again, not replayed.",
            ),
        ] = False,
    ) -> None:
        """Measure range, bounds, velocity and consistency of the fusion filter (and the thesis's method)."""
        from estimators.errors import ConfigError
        from pipeline.accuracy import AccuracyOptions, run_accuracy, settings_from_overrides

        if mode not in ("bearings", "pipeline"):
            raise ConfigError(f"accuracy --mode: expected 'bearings' or 'pipeline', got {mode!r}")
        overrides = tuple(override or ())
        if overrides and mode != "pipeline" and any(
                not o.strip().startswith("fusion.") for o in overrides):
            raise ConfigError("accuracy --override: bearings mode runs only the fusion (fusion.* keys); "
                              f"got {', '.join(overrides)}; use --mode pipeline for front-end keys")
        # options of one mode have no effect in the other: refused there, as an unknown flag would be,
        # each named as typed
        cache_flag = "--render-cache" if render_cache else "--no-render-cache"
        other = {"bearings": {"--reuse-frontend": reuse_frontend or None, cache_flag: render_cache},
                 "pipeline": {"--pixel-sigma": pixel_sigma, "--seed": seed, "--n-random": n_random}}[mode]
        given = [flag for flag, value in other.items() if value is not None]
        if given:
            needs = "pipeline" if mode == "bearings" else "bearings"
            raise ConfigError(f"accuracy {', '.join(given)}: {needs} mode only, no effect in {mode} mode; "
                              f"drop {'it' if len(given) == 1 else 'them'} or give --mode {needs}")
        chosen = {"pixel_sigma_px": pixel_sigma, "seed": seed, "render_cache": render_cache}
        opts = AccuracyOptions(
            mode=mode, quick=quick, n_random=n_random,
            thesis_interval_s=thesis_interval, scenes=tuple(scene) if scene else None,
            settings=settings_from_overrides(overrides, max_speed), reuse_frontend=reuse_frontend,
            scene_set=scene_set, overrides=overrides, **{k: v for k, v in chosen.items() if v is not None},
        )
        res = run_accuracy(opts, out, progress=lambda s: typer.echo(s, err=True))
        typer.echo(res["table"])
        typer.echo(f"elapsed {res['elapsed_s']:.1f} s" + (f"; wrote {res['written']}" if out else ""))
