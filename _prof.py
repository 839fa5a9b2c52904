import time, numpy as np
from numba import njit
from gyro_platform.engine.simulator import Simulator
from gyro_platform.physics.options import ModelOptions
from gyro_platform.physics.params import NAV1
from gyro_platform.engine.inputs import RateSample
from gyro_platform.engine import output_kernel as ok
from gyro_platform.physics.tree import kinematics, newton_euler, rotor_torques
from gyro_platform.physics.rotations import matrix_rotvec, rotvec_matrix, euler_xyz

@njit
def loop_rhs(N, y, yd, fid, args):
    s = 0
    for i in range(N):
        s += ok._rhs(0.001, y, yd, fid, *args)
    return s

@njit
def loop_kin(N, parent, jtype, axis, qidx, vidx, stab, y, v, w0, R, w, J, inertia, rhost, raxis, L, a, wd0, tau, wd, f, rC, rA, rt):
    for i in range(N):
        kinematics(parent, jtype, axis, qidx, vidx, stab, y, v, w0, R, w, J)
        newton_euler(parent, jtype, axis, vidx, inertia, stab, rhost, raxis, L, v, a, wd0, R, w, True, True, tau, wd, f)
        rotor_torques(rhost, raxis, rC, rA, L, w, wd, rt)

@njit
def loop_rot(N, R, v):
    s = 0.0
    for i in range(N):
        d = matrix_rotvec(R); r = rotvec_matrix(v); e = euler_xyz(R)
        s += d[0] + r[0,0] + e[0]
    return s

@njit
def loop_alloc(N):
    s=0.0
    for i in range(N):
        a=np.empty(3); s+=a.shape[0]
    return s

def med(fn, r=5):
    ts=[]
    for _ in range(r):
        t=time.process_time(); fn(); ts.append(time.process_time()-t)
    return sorted(ts)[r//2]
N=20000
for mode,fid in (("stabilised","linear"),("stabilised","full"),("carried","full")):
    sim=Simulator(NAV1, ModelOptions.make(mode,fid))
    sim.push(RateSample.of(0,[0.1,0.2,0.3])); sim.push(RateSample.of(0.01,[0.1,0.2,0.3]))
    s=sim.system; y=sim.y.copy(); yd=np.empty_like(y)
    args=s.kernel_args()
    loop_rhs(1,y,yd,s.fid,args)
    print(mode,fid,'rhs us', med(lambda: loop_rhs(N,y,yd,s.fid,args))/N*1e6)
    tr=s.tree; wk=s.work
    v=y[5:5+tr.nv].copy(); a=np.zeros(tr.nv); w0=np.zeros(3)
    A=(tr.parent, tr.jtype, tr.axis, tr.qidx, tr.vidx, tr.root_dynamic, y, v, w0, wk.R, wk.w, wk.J, tr.inertia, tr.rotor_host, tr.rotor_axis, np.asarray(NAV1.L,float), a, w0, wk.tau_ext, wk.wd, wk.f, tr.rotor_C, tr.rotor_A, np.zeros((3,3)))
    loop_kin(1,*A)
    print('  kin+NE+rotor us', med(lambda: loop_kin(N,*A))/N*1e6)
R=np.eye(3); vv=np.array([0.1,0.2,0.3]); loop_rot(1,R,vv); loop_alloc(1)
print('rot3 us', med(lambda: loop_rot(N,R,vv))/N*1e6)
print('alloc us', med(lambda: loop_alloc(N))/N*1e6)
