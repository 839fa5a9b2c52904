import time, numpy as np
from gyro_platform.engine import outputs as O
def med(fn, n=5000, r=7):
    ts=[]
    for _ in range(r):
        t=time.process_time()
        for _ in range(n): fn()
        ts.append((time.process_time()-t)/n*1e6)
    return sorted(ts)[r//2]
row=np.zeros(O.N_COL); get=row.__getitem__
print('ofrow', med(lambda: O.outputs_of_row(row, True)))
print('map gimbal', med(lambda: tuple(map(get, O._SL_GIMBAL))))
print('status', med(lambda: {"a": row.item(O.C_MARGIN), "b": row.item(O.C_MAXANG), "c": row.item(O.C_NSTEPS)}))
print('bear dict', med(lambda: dict(zip(O.BEARING_NAMES, map(get, O._SL_BEAR)))))
print('one slice', med(lambda: get(O._SL_QUAT)))
print('item', med(lambda: row.item(0)))
