"""Packaging of swarm_eval (ament_python): every study and report is a console script,
``ros2 run swarm_eval NAME`` (the files of scripts/ and benchmarks/ wrap the same mains)."""

from setuptools import find_packages, setup

PACKAGE = 'swarm_eval'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Swarm Formation Engineering',
    maintainer_email='engineering@swarm-formation.dev',
    description='Headless evaluator, studies, reports and benchmark suite of the swarm.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'evaluate = swarm_eval.evaluate:main',
            'fault_study = swarm_eval.fault_study:main',
            'method_study = swarm_eval.method_study:main',
            'mesh_study = swarm_eval.mesh_study:main',
            'shape_study = swarm_eval.shape_study_cli:main',
            'localization_study = swarm_eval.localization_study:main',
            'lqr_report = swarm_eval.lqr_report:main',
            'partition = swarm_eval.partition_report:main',
            'sim_benchmark = swarm_eval.sim_benchmark:main',
            'bench_dsdv = swarm_eval.bench.dsdv:main',
            'benchmarks = swarm_eval.bench.suite:main',
            'measure = swarm_eval.measured:main',
        ],
    },
)
