"""hexsim in a user's toolchain: ``hexsim serve``, a real-time virtual motion system on UDP
(:mod:`~hexsim.interfaces.server`, its packets :mod:`~hexsim.interfaces.packets`, the operating modes
:mod:`~hexsim.interfaces.operating_modes`, a host client :mod:`~hexsim.interfaces.host`). docs/serve.md."""
