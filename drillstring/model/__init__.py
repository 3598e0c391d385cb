"""The model of Section II: parameters, the stepping engine, the monolithic simulation, the
controller law, the digital top-drive laws and their sampled loop, and the paper's experiments
(``docs/model.md``, ``docs/controllers.md``). The package root ``drillstring`` re-exports the
user API; the rest is imported from its module."""
