"""Where the skin's fold crease lies before and after simulations with the fold lowered
by 0 and 10 mm (docs/dev/standing-frame.md, "Does the simulated skin show the new
fold?"). Run in a folder holding ph.ply and ph.json (`mammaplan phantom`) and the
simulation folders sim0/ and sim10/. Needs numpy and plyfile."""
import json,numpy as np
from plyfile import PlyData
def load(p):
    d=PlyData.read(p)['vertex']; return np.c_[d['x'],d['y'],d['z']]
lm=json.load(open('ph.json'))['landmarks']
def crease(P, side, dx=0.0):
    f=np.array(lm['PSMF'+side]); x0=f[0]+dx
    sel=(np.abs(P[:,0]-x0)<2)&(P[:,2]>f[2]-60)
    Q=P[sel]; ys=np.arange(f[1]-40, f[1]+30, 1.0); z=[]
    for y in ys:
        m=np.abs(Q[:,1]-y)<1.0
        z.append(Q[m,2].max() if m.any() else np.nan)
    z=np.array(z); z=np.convolve(np.nan_to_num(z),np.ones(3)/3,'same')
    d2=z[2:]-2*z[1:-1]+z[:-2]
    k=np.argmax(d2[3:-3])+4
    return ys[k]-f[1]
pre=load('ph.ply'); s0=load('sim0/simulated_scan.ply'); s10=load('sim10/simulated_scan.ply')
for side in ('l','r'):
  for dx in (-10,0,10):
    a,b,c=crease(pre,side,dx),crease(s0,side,dx),crease(s10,side,dx)
    print(side,dx,'crease rel. PSMF: pre %.0f  lowering0 %.0f  lowering10 %.0f  -> moved by the 10 mm lowering: %.0f mm'%(a,b,c,b-c))
