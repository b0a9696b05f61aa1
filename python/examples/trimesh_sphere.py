"""trimesh in, flow out: a texture turning on an icosphere, its flow, and a picture.

    pip install ./python trimesh matplotlib
    python python/examples/trimesh_sphere.py          # writes trimesh_sphere.png
"""

import matplotlib

matplotlib.use("Agg")  # no window needed
import matplotlib.pyplot as plt
import numpy as np
import trimesh

import meshflow

# A unit icosphere (2562 vertices) and a grey-value pattern turning about z by 0.05 rad per
# frame over 5 frames; the surface itself stays put.
sphere = trimesh.creation.icosphere(subdivisions=4)
omega, frames = 0.05, 5


def texture(p):
    return 0.5 + 0.2 * np.sin(3 * p[:, 0] + 1) * np.cos(2 * p[:, 1]) + 0.15 * np.sin(4 * p[:, 2] - p[:, 0])


def turned(points, angle):
    c, s = np.cos(angle), np.sin(angle)
    return points @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


positions = np.repeat(sphere.vertices[None], frames, axis=0)            # (K, V, 3)
intensity = np.stack([texture(turned(sphere.vertices, omega * k)) for k in range(frames)])

flow = meshflow.compute_flow(positions, sphere.faces, intensity, large_motion=True)
print(flow)
print("weights used:", flow.weights)

# Against the true flow ω ẑ × x: the angle between computed and true vectors.
truth = omega * np.cross([0, 0, 1], sphere.vertices)
u = flow.vectors[0]
moving = np.linalg.norm(truth, axis=1) > 0.1 * omega  # away from the poles
a, b = u[moving], truth[moving]
cosine = np.sum(a * b, axis=1) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
print(f"mean direction error where it moves: {np.degrees(np.arccos(np.clip(cosine, -1, 1))).mean():.2f}°")
print(f"median speed ratio: {np.median(np.linalg.norm(a, axis=1) / np.linalg.norm(b, axis=1)):.3f}")

# The picture: the image on the sphere, and every 8th vector as an arrow (front half).
figure = plt.figure(figsize=(6, 6))
axes = figure.add_subplot(projection="3d")
grey = intensity[0][sphere.faces].mean(axis=1)
surface = axes.plot_trisurf(*sphere.vertices.T, triangles=sphere.faces, linewidth=0, antialiased=False)
surface.set_array(grey)
surface.set_cmap("gray")
front = np.nonzero(sphere.vertices @ np.array([1.0, -1.0, 0.6]) > 0.3)[0][::8]
tips = sphere.vertices[front] * 1.01
axes.quiver(*tips.T, *(u[front] * 5).T, color="orangered", linewidth=1.2)
axes.view_init(elev=25, azim=-45)
axes.set_box_aspect((1, 1, 1))
axes.set_axis_off()
figure.savefig("trimesh_sphere.png", dpi=110, bbox_inches="tight")
print("wrote trimesh_sphere.png")
