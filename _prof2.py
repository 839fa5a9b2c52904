import time, numpy as np
from gyro_platform.engine.simulator import Simulator
from gyro_platform.physics.options import ModelOptions
from gyro_platform.physics.params import NAV1
from gyro_platform.engine.inputs import RateSample
from gyro_platform.engine.output_kernel import output_row
from gyro_platform.engine.outputs import outputs_of_row, N_COL, Outputs
from numba import njit
@njit
def f1(a): return a[0]
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
out=np.empty(N_COL); a=np.zeros(3); f1(a)
print('f1', med(lambda: f1(a)))
print('outputs()', med(sim.outputs))
print('kernel call', med(lambda: output_row(0.01, 0.01, 5, sim.y, s.seg, out, s.I, s.P, s.mats, k.CF, k.OI, k.E, k.WK)))
row=out.copy()
print('outputs_of_row', med(lambda: outputs_of_row(row, True)))
S=[slice(i*3,i*3+3) for i in range(21)]
print('21 slices', med(lambda: [row[s] for s in S]))
print('Outputs()', med(lambda: Outputs(t=1.0, gimbal_angles=a, gimbal_rates=a, gimbal_axial_torques=a, platform_rate=a, platform_attitude=a, drift_angle=a, drift_rate=a, bearing_torques={}, motor_torques=a, mount_angles=a, mount_rates=a, servo_torque=a, rotor_rates=a, status={})))
for _ in range(3):
    print('outputs()', med(sim.outputs), 'row', med(lambda: k.row(0.01, 0.01, 5, sim.y, s.seg)), 'kernel', med(lambda: output_row(0.01, 0.01, 5, sim.y, s.seg, out, s.I, s.P, s.mats, k.CF, k.OI, k.E, k.WK)), 'ofrow', med(lambda: outputs_of_row(row, True)))
import cProfile, pstats
cProfile.run('for _ in range(20000): sim.outputs()', '/tmp/prof.out')
pstats.Stats('/tmp/prof.out').sort_stats('tottime').print_stats(8)
