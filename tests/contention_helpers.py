"""Hand-made contention worlds for the engine's tests: a scripted dispatcher and the engine run
over a block of given work, transfer and propagation times (no traces, no edge world)."""

from __future__ import annotations

import math

from yafs_safetail.contention.engine import (
    EngineSettings,
    FirstReply,
    RequestBlock,
    ServerSpec,
    run_engine,
)
from yafs_safetail.edge.energy import RadioPowerModel

RADIO = RadioPowerModel()


class Fixed:
    """Sends request j to ``plan[j]`` and keeps the outcomes by request."""

    wants_outcomes = True

    def __init__(self, plan, mode="all", delay_s=math.inf):
        self.plan, self.mode, self.delay_s = plan, mode, delay_s
        self.outcomes: dict[int, FirstReply] = {}

    def choose(self, request, active_users):
        return self.plan[request]

    def hedge_delay_s(self):
        return self.delay_s

    def completed(self, reply):
        self.outcomes[reply.request] = reply


def run_hand_made(work, emit, plan, *, outages=(), slots, speed, rtt, input_s=0.0, output_s=0.0,
                  input_bytes=None, output_bytes=None, cancel=True, queue=False, timeout_s=math.inf,
                  mode="all", delay_s=math.inf, shared=True, fallback_latency_s, per_process_w,
                  radio: RadioPowerModel | None = None):
    """The engine over one block: ``work[j][i]`` is request j's work on server i; every copy's
    transfer terms and RTT are the same; ``radio`` None charges the device nothing."""
    n_servers = len(work[0])
    sizes = {} if input_bytes is None else {"input_bytes": [input_bytes] * len(work),
                                            "output_bytes": [output_bytes or 0.0] * len(work)}
    block = RequestBlock(first=0, input_transfer_s=[[input_s] * n_servers for _ in work],
                         output_transfer_s=[[output_s] * n_servers for _ in work],
                         propagation_s=[[rtt] * n_servers for _ in work], work_s=work, **sizes)
    radio_settings = {} if radio is None else {
        "radio_up_j_per_byte": 8.0 * radio.alpha_up_w_per_bps,
        "radio_down_j_per_byte": 8.0 * radio.alpha_down_w_per_bps, "radio_active_w": radio.beta_w}
    settings = EngineSettings(servers=tuple(ServerSpec(slots, speed) for _ in range(n_servers)),
                              contention_levels=1, queue=queue, cancel=cancel, fallback_latency_s=fallback_latency_s,
                              shared_links=shared, outages=outages, timeout_s=timeout_s,
                              per_process_w=per_process_w, **radio_settings)
    dispatcher = Fixed(plan, mode, delay_s)
    return run_engine(settings, emit, len(work), lambda _: block, dispatcher), dispatcher
