"""Confronting the model with measured data: reading a log (:mod:`.measurement`), replaying it through the
plant (:mod:`.replay`, :mod:`.hexapod_replay`), residual analysis (:mod:`.residuals`), fitting candidate
effects and discovering missing ones (:mod:`.candidates`, :mod:`.identify`, :mod:`.discovery`), the
validation verdict (:mod:`.validation`) and the Stribeck friction fit (:mod:`.friction_id`)."""
