"""Rule build_env: one procedural environment map (equirect EXR) and its preview."""

import functools

from freqbrdf.scene import envmaps
from freqbrdf.util.io import write_exr, write_png
from freqbrdf.util.colour import tonemap
from freqbrdf.util.logs import run_script


def main(smk, log):
    settings = dict(smk.params.settings)
    kind = settings.pop("kind")
    width = settings.pop("blur", 0.0)
    if kind == "sunny":
        # Only the sunny sky needs Mitsuba (its sunsky model), so only it pays the JIT start-up.
        from freqbrdf.util.mitsuba_setup import setup_mitsuba
        from freqbrdf.scene.render import sunsky

        settings["sky"] = functools.partial(sunsky, setup_mitsuba(smk.params.variant, smk.threads))
    env = envmaps.blur(getattr(envmaps, kind)(smk.params.height, **settings), width)
    env = envmaps.normalise(env, smk.params.mean_radiance)
    log.info("%s (%s, blur %g): %s, max radiance %.1f", smk.wildcards.env, kind, width, env.shape, env.max())
    write_exr(smk.output.exr, env)
    write_png(smk.output.preview, tonemap(env))


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
