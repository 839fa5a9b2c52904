import time, numpy as np
from numba import njit
@njit(cache=False)
def ret21():
    return (np.empty(5),np.empty(5),np.empty(5),np.empty(3),np.empty(4),np.empty(3),np.empty(3),np.empty(3),np.empty(3),np.empty(3),np.empty(3),np.empty(3),
            np.empty(3),np.empty(3),np.empty(3),np.empty(3),np.empty(3),np.empty(3),np.empty(3),np.empty(3),np.empty(3))
@njit(cache=False)
def ret1():
    return np.empty(74)
ret21(); ret1()
def med(fn, n=5000, r=7):
    ts=[]
    for _ in range(r):
        t=time.process_time()
        for _ in range(n): fn()
        ts.append((time.process_time()-t)/n*1e6)
    return sorted(ts)[r//2]
print('ret21', med(ret21)); print('ret1', med(ret1))
row=np.empty(74)
S=[slice(i*3,i*3+3) for i in range(21)]
print('21 slices', med(lambda: [row[s] for s in S]))
b=row[:27].reshape(9,3)
print('9 int idx', med(lambda: [b[i] for i in range(9)]))
print('list(b)', med(lambda: list(b)))
print('np.split', med(lambda: np.split(row[:63], 21)))
print('21 np.empty', med(lambda: [np.empty(3) for _ in range(21)]))
print('21 copies of slices', med(lambda: [row[s].copy() for s in S]))
