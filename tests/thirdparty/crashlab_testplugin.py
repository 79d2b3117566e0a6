"""A third-party collision model as the registry sees one: found through an entry point
(crashlab_testplugin-0.1.dist-info/entry_points.txt beside this file; tests put this folder on sys.path),
deriving from crashlab.CollisionModel with its own option schema. It delegates the physics to the built-in
impulse model through the public API only, under option names of its own, so the comparison studies can be
shown to find and sweep a plugin's accuracy knobs."""
import crashlab
from crashlab.options import ModelOptions, option


class DelegatingModel(crashlab.CollisionModel):
    name = "testplugin"

    class Options(ModelOptions):
        step: float = option(0.005, "largest integration step", "s", accuracy="smaller", gt=0, le=0.05)
        contact_tolerance: float = option(1e-5, "overlap at which a contact onset is located", "m",
                                          accuracy="smaller", gt=0, le=0.1)

    def __init__(self, **options):
        super().__init__(**options)
        self._inner = crashlab.get_model("impulse", dt=self.options.step, coarse_dt=max(0.05, self.options.step),
                                         onset_tol=self.options.contact_tolerance)

    def simulate(self, scene):
        out = self._inner.simulate(scene)
        out.model = self.name
        return out
