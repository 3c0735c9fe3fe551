"""The hydraulic plant of one leg and the rigid-body model it drives.

Seed chapter 3: the proportional valve with overlap (:mod:`.hydraulics`, eq. 3.1–3.4), the bottom-chamber
pressure with bulk modulus (3.5–3.8), Stribeck friction (3.9), written once in the compiled leg step
(:mod:`.legs`); the seed's parameters (:mod:`.params`, appendix A) and machine files (:mod:`.machine`: valve, cylinder,
supply, load and controller of one machine, the built-in Micro Motion System by default);
effects beyond the seed (:mod:`.effects`), faults (:mod:`.faults`), oil temperature (:mod:`.temperature`);
the MJCF models and the facts Python reads from them (:mod:`.model`), and the platform-only model built
from the MJCF, the default for hexapod runs (:mod:`.platform`).
"""
