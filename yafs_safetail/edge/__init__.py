"""The paper's edge world (§V-A): the published figures, the traces and their readers, the
scenario files, Eq. 1 and Eq. 4, and the pre-drawn worlds every engine and the contention world run on.

It knows nothing of YAFS or of any method; ``sim`` joins it to the YAFS core.
"""
