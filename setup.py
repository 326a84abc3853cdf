"""ament_python install script for bridge_shadow."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "bridge_shadow"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*", "benchmarks"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
    ],
    python_requires=">=3.10",
    install_requires=[
        "numpy>=1.24",
        "scipy>=1.11",
        # 2.0.0 has the 1-D z shape bug (DESIGN 7); estimate/settlement/kalman.py passes z as a column and
        # test/test_kalman.py checks the workaround against this exact version.
        "filterpy==2.0.0",
        "rosbags>=0.10",
        "pyyaml>=6",
        "meshio>=5.3",
        "matplotlib>=3.7",
        # the engine of everything that scales out: archives, gap folds, calibration, seed studies
        # (bridge_shadow/engine.py); a local cluster by default, any scheduler by address
        "dask>=2024.1",
        "distributed>=2024.1",
    ],
    extras_require={
        "ros": ["ros-jazzy-rclpy[fastrtps]", "ros-jazzy-common-interfaces"],
        # ruff within one minor release: its formatter's style changes between minor releases, and
        # the tests check the format (test/test_lint.py)
        "test": ["pytest>=7", "pytest-xdist>=3", "ruff>=0.17,<0.18"],
        # METIS nested-dissection ordering: about 1.6x faster factorization (fe/solve.py uses it
        # when importable and falls back to SuperLU's own ordering otherwise).
        "fast": ["pymetis>=2023.1"],
        # Optional, never installed by `make`: CHOLMOD factorization (GPL; builds on Debian's
        # libsuitesparse-dev) and OpenSeesPy for benchmarks/fe_scaling.py (needs libblas3, liblapack3).
        "cholmod": ["scikit-sparse==0.4.16"],  # newer releases do not build on Debian 12's SuiteSparse 5
        "opensees": ["openseespy>=3.5"],
    },
    zip_safe=True,
    maintainer="bridge_shadow developers",
    description="Digital shadow of the UniBw Munich test bridge (ROS 2 Jazzy).",
    license="MIT",
    entry_points={
        "console_scripts": [
            "bridge-shadow = bridge_shadow.cli:main",
            "bridge_shadow_node = bridge_shadow.ros.main:main",
            "bridge_shadow_fleet = bridge_shadow.ros.fleet:main",
        ],
    },
)
