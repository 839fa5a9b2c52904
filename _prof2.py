import time, numpy as np
from gyro_platform.engine.simulator import Simulator
from gyro_platform.physics.options import ModelOptions
from gyro_platform.physics.params import NAV1
from gyro_platform.engine.inputs import RateSample
from gyro_platform.engine.output_kernel import output_row
from gyro_platform.engine.outputs import outputs_of_row, N_COL
def med(fn, n=5000, r=7):
    ts=[]
    for _ in range(r):
        t=time.process_time()
        for _ in range(n): fn()
        ts.append((time.process_time()-t)/n*1e6)
    return sorted(ts)[r//2]
sim=Simulator(NAV1, ModelOptions.make("stabilised","linear"))
sim.push(RateSample.of(0,[0.1,0.2,0.3])); sim.push(RateSample.of(0.01,[0.1,0.2,0.3]))
k=sim._outk; s=sim.system
out=np.empty(N_COL)
print('outputs()', med(sim.outputs))
print('kernel call', med(lambda: output_row(0.01, 0.01, 5, sim.y, s.seg, out, s.I, s.P, s.mats, k.CF, k.OI, k.E)))
print('outputs_of_row', med(lambda: outputs_of_row(out.copy(), True)))
print('np.empty', med(lambda: np.empty(N_COL)))
row=out.copy()
print('reshape+unpack vec', med(lambda: tuple(row[16:67].reshape(17,3))))
