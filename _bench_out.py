import sys, time, numpy as np
sys.path.insert(0, "test")
from test_output_block import reference_outputs, _drive, _snapshots_along
from gyro_platform.engine.simulator import Simulator
from gyro_platform.physics.options import ModelOptions
from gyro_platform.physics.params import NAV1
def med(fn, n, r=7):
    ts=[]
    for _ in range(r):
        t=time.process_time()
        for _ in range(n): fn()
        ts.append((time.process_time()-t)/n*1e6)
    return sorted(ts)[r//2]
print(f"{'config':28s} {'outputs() us':>12s} {'reference us':>12s} {'block us/inst':>13s} {'kernel only':>11s}")
for mode, fid in (("stabilised","linear"),("stabilised","full"),("stabilised","precession"),("carried","full"),("carried","precession")):
    sim=Simulator(NAV1, ModelOptions.make(mode,fid))
    rng=np.random.default_rng(0)
    snaps,_=_snapshots_along(sim, 200, rng)
    a=med(sim.outputs, 2000)
    b=med(lambda: reference_outputs(sim), 200)
    c=med(lambda: sim._outputs_at(snaps), 20)/200
    k=sim._outk
    from gyro_platform.engine.output_kernel import output_rows
    from gyro_platform.engine.outputs import N_COL
    OUT=np.empty((200,N_COL)); s=sim.system
    T=snaps.t; TR=snaps.t_rel; NS=snaps.n_steps.astype(float); Y=snaps.y; SEG=snaps.seg
    d=med(lambda: output_rows(T,TR,NS,Y,SEG,OUT,s.I,s.P,s.mats,k.CF,k.OI,k.E,k.WK), 20)/200
    print(f"{mode+'/'+fid:28s} {a:12.2f} {b:12.1f} {c:13.2f} {d:11.2f}")
